"""Goals and stops a ground station sends the rover over MAVLink, and the rover's answers.

Goals come two ways, as ground stations send them: ``SET_POSITION_TARGET_GLOBAL_INT`` (answered the
standard way, by echoing the accepted target in ``POSITION_TARGET_GLOBAL_INT``) and ``COMMAND_INT`` with
``MAV_CMD_DO_REPOSITION`` (answered with ``COMMAND_ACK``). Latitude and longitude are degrees x 1e7.

An emergency stop comes as ``COMMAND_LONG`` or ``COMMAND_INT`` carrying ``MAV_CMD_COMPONENT_ARM_DISARM``
with param1 = 0 (disarm; param2 = 21196 forces it, and is taken the same way) or
``MAV_CMD_DO_FLIGHTTERMINATION`` with param1 = 1; it is answered with ``COMMAND_ACK`` (ACCEPTED).
A stop is never refused for a reason the sender could not fix (a refused stop is the unsafe answer).

A mission start comes as ``COMMAND_LONG`` or ``COMMAND_INT`` carrying ``MAV_CMD_MISSION_START`` (param1 the
first item, param2 the last): it belongs to the mission, so the link hands it to the mission server
(``firmware_bridge.mavlink_mission``), which judges it here against the mission it holds
(``judge_mission_start``) and answers with ``COMMAND_ACK``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import common as mavlink2

# Frames whose x/y are WGS84 latitude/longitude (altitude reference differs; a rover ignores altitude).
GLOBAL_FRAMES = frozenset(
    {
        mavlink2.MAV_FRAME_GLOBAL,
        mavlink2.MAV_FRAME_GLOBAL_INT,
        mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT,
        mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
    }
)
# MAV_CMD_COMPONENT_ARM_DISARM param2 magic number: disarm even when the vehicle thinks it unsafe.
FORCE_DISARM_MAGIC = 21196
# type_mask bits 0..2: ignore x / y / z position.
_IGNORE_POSITION_XY = 0b011
COMMAND_MESSAGES = frozenset({"COMMAND_INT", "COMMAND_LONG", "SET_POSITION_TARGET_GLOBAL_INT"})
STATUSTEXT_CHUNK = 50  # characters per STATUSTEXT frame


@dataclass(frozen=True)
class GoalRequest:
    """A goal from a ground station: WGS84 degrees; how it came and from whom (for the answer)."""

    t_ns: int
    lat_deg: float
    lon_deg: float
    source: str  # "SET_POSITION_TARGET_GLOBAL_INT" or "MAV_CMD_DO_REPOSITION"
    sysid: int
    compid: int


@dataclass(frozen=True)
class StopRequest:
    """An emergency stop from a ground station: when, which command carried it, and from whom."""

    t_ns: int
    source: str  # "MAV_CMD_COMPONENT_ARM_DISARM" or "MAV_CMD_DO_FLIGHTTERMINATION"
    sysid: int
    compid: int


@dataclass(frozen=True)
class StartRequest:
    """MAV_CMD_MISSION_START from a ground station: drive the mission from item ``first`` to its end."""

    t_ns: int
    first: int
    sysid: int
    compid: int


@dataclass(frozen=True)
class Verdict:
    """What to do with one command message: a goal, a stop, a mission start, or why not, and the MAV_RESULT
    to answer with."""

    goal: GoalRequest | None
    result: int
    reason: str
    stop: StopRequest | None = None
    start: StartRequest | None = None


def is_mission_start(msg: Any) -> bool:
    """A COMMAND_LONG / COMMAND_INT carrying MAV_CMD_MISSION_START (the mission server's, not a goal)."""
    return getattr(msg, "command", None) == mavlink2.MAV_CMD_MISSION_START


def addressed_to(msg: Any, system_id: int, component_id: int) -> bool:
    """True if the message targets us (0 = broadcast, as MAVLink routing says)."""
    return msg.target_system in (0, system_id) and msg.target_component in (0, component_id)


def _position(lat_e7: int, lon_e7: int) -> tuple[float, float] | None:
    lat, lon = lat_e7 * 1e-7, lon_e7 * 1e-7
    if not (math.isfinite(lat) and math.isfinite(lon) and -90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        return None
    return lat, lon


def judge_command(msg: Any, t_ns: int) -> Verdict:
    """Turn a command message addressed to us into a goal, or a refusal naming the reason."""
    kind = msg.get_type()
    sysid, compid = msg.get_srcSystem(), msg.get_srcComponent()
    if kind == "SET_POSITION_TARGET_GLOBAL_INT":
        if msg.coordinate_frame not in GLOBAL_FRAMES:
            return Verdict(None, mavlink2.MAV_RESULT_DENIED, f"frame {msg.coordinate_frame} is not global")
        if msg.type_mask & _IGNORE_POSITION_XY:
            return Verdict(None, mavlink2.MAV_RESULT_UNSUPPORTED, "only position targets are supported")
        position = _position(msg.lat_int, msg.lon_int)
        source = kind
    elif kind in ("COMMAND_LONG", "COMMAND_INT") and msg.command in _STOP_COMMANDS:
        return _judge_stop(msg, t_ns)
    elif kind == "COMMAND_INT" and msg.command == mavlink2.MAV_CMD_DO_REPOSITION:
        if msg.frame not in GLOBAL_FRAMES:
            return Verdict(None, mavlink2.MAV_RESULT_DENIED, f"frame {msg.frame} is not global")
        position = _position(msg.x, msg.y)
        source = "MAV_CMD_DO_REPOSITION"
    else:
        command = getattr(msg, "command", None)
        return Verdict(None, mavlink2.MAV_RESULT_UNSUPPORTED, f"{kind} {command} not supported")
    if position is None:
        return Verdict(None, mavlink2.MAV_RESULT_DENIED, "latitude/longitude out of range")
    goal = GoalRequest(t_ns, position[0], position[1], source, sysid, compid)
    return Verdict(goal, mavlink2.MAV_RESULT_ACCEPTED, "goal accepted")


_STOP_COMMANDS = {
    mavlink2.MAV_CMD_COMPONENT_ARM_DISARM: "MAV_CMD_COMPONENT_ARM_DISARM",
    mavlink2.MAV_CMD_DO_FLIGHTTERMINATION: "MAV_CMD_DO_FLIGHTTERMINATION",
}


def _judge_stop(msg: Any, t_ns: int) -> Verdict:
    """ARM_DISARM / FLIGHTTERMINATION (COMMAND_LONG or COMMAND_INT: both carry param1 and param2)."""
    name = _STOP_COMMANDS[msg.command]
    param1 = msg.param1
    if msg.command == mavlink2.MAV_CMD_COMPONENT_ARM_DISARM:
        if param1 == 1.0:
            # Arming is the autopilot's business; the companion never arms itself on a ground station's word.
            return Verdict(None, mavlink2.MAV_RESULT_UNSUPPORTED, "arming is not taken by the companion")
        if param1 != 0.0:
            return Verdict(None, mavlink2.MAV_RESULT_DENIED, f"disarm param1 {param1} is not 0 or 1")
        forced = msg.param2 == FORCE_DISARM_MAGIC
        reason = "forced disarm: emergency stop" if forced else "disarm: emergency stop"
    else:
        if not param1 > 0.5:
            # Clearing termination would restart motors remotely: the latched e-stop clears only on a
            # deliberate resume (cmd/resume on Zenoh), not on this or on a new goal.
            return Verdict(
                None, mavlink2.MAV_RESULT_UNSUPPORTED, "clearing flight termination is not supported"
            )
        reason = "flight termination: emergency stop"
    stop = StopRequest(t_ns, name, msg.get_srcSystem(), msg.get_srcComponent())
    return Verdict(None, mavlink2.MAV_RESULT_ACCEPTED, reason, stop=stop)


def judge_mission_start(msg: Any, t_ns: int, item_count: int) -> Verdict:
    """MAV_CMD_MISSION_START against a mission of ``item_count`` items: param1, the first item, any the
    mission has; param2, the last item, 0 or the mission's last index (driven to its end: stopping at an
    earlier item is not supported)."""
    first, last = msg.param1, msg.param2
    if item_count == 0:
        return Verdict(None, mavlink2.MAV_RESULT_DENIED, "mission start: there is no mission")
    items = f"items 0..{item_count - 1}"
    if not (math.isfinite(first) and first == int(first) and 0 <= first < item_count):
        return Verdict(None, mavlink2.MAV_RESULT_DENIED, f"mission start: first item {first} not in {items}")
    if not (last == 0 or last == item_count - 1):
        return Verdict(
            None,
            mavlink2.MAV_RESULT_UNSUPPORTED,
            f"mission start: last item {last}: only 0 or {item_count - 1} (to the end) is supported",
        )
    start = StartRequest(t_ns, int(first), msg.get_srcSystem(), msg.get_srcComponent())
    return Verdict(None, mavlink2.MAV_RESULT_ACCEPTED, f"mission started at item {int(first)}", start=start)


def statustext_chunks(text: str) -> list[bytes]:
    """STATUSTEXT carries 50 bytes; longer text goes in numbered chunks (MAVLink 2 ``id``/``chunk_seq``)."""
    data = text.encode("utf-8", errors="replace")
    if len(data) <= STATUSTEXT_CHUNK:
        return [data]
    return [data[i : i + STATUSTEXT_CHUNK] for i in range(0, len(data), STATUSTEXT_CHUNK)]
