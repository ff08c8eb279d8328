"""Goals a ground station sends the rover over MAVLink, and the rover's answers.

Two ways in, as ground stations send them: ``SET_POSITION_TARGET_GLOBAL_INT`` (answered the standard way,
by echoing the accepted target in ``POSITION_TARGET_GLOBAL_INT``) and ``COMMAND_INT`` with
``MAV_CMD_DO_REPOSITION`` (answered with ``COMMAND_ACK``). Latitude and longitude are degrees x 1e7.
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
class Verdict:
    """What to do with one command message: a goal, or why not, and the MAV_RESULT to answer with."""

    goal: GoalRequest | None
    result: int
    reason: str


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


def statustext_chunks(text: str) -> list[bytes]:
    """STATUSTEXT carries 50 bytes; longer text goes in numbered chunks (MAVLink 2 ``id``/``chunk_seq``)."""
    data = text.encode("utf-8", errors="replace")
    if len(data) <= STATUSTEXT_CHUNK:
        return [data]
    return [data[i : i + STATUSTEXT_CHUNK] for i in range(0, len(data), STATUSTEXT_CHUNK)]
