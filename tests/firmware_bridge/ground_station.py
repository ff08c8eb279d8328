"""A pymavlink ground station for mission tests: it packs and sends what a GCS sends (its own ids), reads
what the rover answered, and answers the rover's item requests from a list, as a ground station does.

It works over any byte transport end (``memory_pipe_pair``'s, or ``ScriptedGroundStation`` below, which
puts it inside the rover's transport for a lockstep trial).
"""

from __future__ import annotations

from typing import Any

from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_transport import PipeEnd, memory_pipe_pair

ROVER = (1, 191)  # the companion's default system / component
MISSION = mavlink2.MAV_MISSION_TYPE_MISSION


def waypoint(
    seq: int,
    lat: float,
    lon: float,
    *,
    frame: int = mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    command: int = mavlink2.MAV_CMD_NAV_WAYPOINT,
    mission_type: int = MISSION,
    target: tuple[int, int] = ROVER,
) -> Any:
    """A MISSION_ITEM_INT as a ground station plans it (lat/lon in degrees; 2 m relative altitude)."""
    return mavlink2.MAVLink_mission_item_int_message(
        *target, seq, frame, command, 0, 1, 0.0, 0.5, 0.0, float("nan"), round(lat * 1e7), round(lon * 1e7),
        2.0, mission_type,
    )  # fmt: skip


def change_speed(
    seq: int,
    speed: float,
    *,
    speed_type: float = mavlink2.SPEED_TYPE_GROUNDSPEED,
    frame: int = mavlink2.MAV_FRAME_MISSION,
    target: tuple[int, int] = ROVER,
) -> Any:
    """A MISSION_ITEM_INT MAV_CMD_DO_CHANGE_SPEED as QGroundControl plans one (no position; throttle -1)."""
    return mavlink2.MAVLink_mission_item_int_message(
        *target, seq, frame, mavlink2.MAV_CMD_DO_CHANGE_SPEED, 0, 1, speed_type, speed, -1.0, 0.0, 0, 0, 0.0,
        MISSION,
    )  # fmt: skip


def return_to_launch(
    seq: int, *, frame: int = mavlink2.MAV_FRAME_MISSION, target: tuple[int, int] = ROVER
) -> Any:
    """A MISSION_ITEM_INT MAV_CMD_NAV_RETURN_TO_LAUNCH as a ground station plans "Return to launch" (no
    position, no parameters)."""
    return mavlink2.MAVLink_mission_item_int_message(
        *target, seq, frame, mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 1, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0,
        MISSION,
    )  # fmt: skip


def do_jump(
    seq: int,
    target: float,
    repeat: float,
    *,
    frame: int = mavlink2.MAV_FRAME_MISSION,
    target_ids: Any = ROVER,
) -> Any:
    """A MISSION_ITEM_INT MAV_CMD_DO_JUMP as a ground station plans "Jump" (param1 the item, param2 the
    repeat count; no position)."""
    return mavlink2.MAVLink_mission_item_int_message(
        *target_ids, seq, frame, mavlink2.MAV_CMD_DO_JUMP, 0, 1, target, repeat, 0.0, 0.0, 0, 0, 0.0, MISSION,
    )  # fmt: skip


def nav_delay(
    seq: int, seconds: float, hour: float = -1.0, minute: float = -1.0, second: float = -1.0
) -> Any:
    """A MISSION_ITEM_INT MAV_CMD_NAV_DELAY (param1 the delay in seconds, or -1 and the UTC time of day in
    params 2-4; no position)."""
    return mavlink2.MAVLink_mission_item_int_message(
        *ROVER, seq, mavlink2.MAV_FRAME_MISSION, mavlink2.MAV_CMD_NAV_DELAY, 0, 1, seconds, hour, minute,
        second, 0, 0, 0.0, MISSION,
    )  # fmt: skip


def loiter(seq: int, lat: float, lon: float, seconds: float | None = None, *, target: Any = ROVER) -> Any:
    """A MISSION_ITEM_INT MAV_CMD_NAV_LOITER_TIME (``seconds`` in param1, radius 2 m in param3) or, with no
    ``seconds``, MAV_CMD_NAV_LOITER_UNLIM (param1 empty), as a ground station plans a loiter."""
    command = mavlink2.MAV_CMD_NAV_LOITER_UNLIM if seconds is None else mavlink2.MAV_CMD_NAV_LOITER_TIME
    return mavlink2.MAVLink_mission_item_int_message(
        *target, seq, mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, command, 0, 1,
        0.0 if seconds is None else seconds, 0.0, 2.0, float("nan"), round(lat * 1e7), round(lon * 1e7), 2.0,
        MISSION,
    )  # fmt: skip


def command_long(command: int, *params: float, target: Any = ROVER) -> Any:
    """A COMMAND_LONG carrying ``command`` with up to seven params (the rest 0)."""
    padded = [*params, *[0.0] * (7 - len(params))]
    return mavlink2.MAVLink_command_long_message(*target, command, 0, *padded)


def mission_start(first: float, last: float, *, kind: str = "COMMAND_LONG", target: Any = ROVER) -> Any:
    """MAV_CMD_MISSION_START (param1 the first item, param2 the last) as COMMAND_LONG or COMMAND_INT."""
    if kind == "COMMAND_INT":
        return mavlink2.MAVLink_command_int_message(
            *target, 0, mavlink2.MAV_CMD_MISSION_START, 0, 0, first, last, 0, 0, 0, 0, 0.0
        )
    return mavlink2.MAVLink_command_long_message(
        *target, mavlink2.MAV_CMD_MISSION_START, 0, first, last, 0, 0, 0, 0, 0
    )


class GroundStation:
    """One end of a MAVLink byte stream, speaking as system ``sysid`` / component ``compid``."""

    def __init__(self, end: Any, sysid: int = 255, compid: int = 190) -> None:
        self.end = end
        self.mav = mavlink2.MAVLink(None, sysid, compid)
        self._parser = mavlink2.MAVLink(None)
        self._parser.robust_parsing = True
        self.heard: list[Any] = []  # every message received, in order

    def send(self, msg: Any) -> None:
        self.end.write(bytes(msg.pack(self.mav)))

    def receive(self) -> list[Any]:
        """What the rover sent since the last call (garbage left out)."""
        messages = [
            m
            for m in self._parser.parse_buffer(self.end.read()) or []
            if not isinstance(m, mavlink2.MAVLink_bad_data)
        ]
        self.heard += messages
        return messages

    def answer(self, items: list[Any], received: list[Any]) -> None:
        """Send the item each MISSION_REQUEST_INT in ``received`` asks for."""
        for msg in received:
            if msg.get_type() == "MISSION_REQUEST_INT" and msg.seq < len(items):
                self.send(items[msg.seq])

    def of_type(self, name: str) -> list[Any]:
        return [m for m in self.heard if m.get_type() == name]


class ScriptedGroundStation:
    """A transport for the rover's ground-station link with a ``GroundStation`` behind it that uploads
    ``items`` once it hears the rover's HEARTBEAT and answers its requests: every time the rover reads, the
    ground station first reads what the rover wrote and answers (one round trip per read)."""

    def __init__(self, items: list[Any]) -> None:
        rover_end, station_end = memory_pipe_pair()
        self._rover_end: PipeEnd = rover_end
        self.station = GroundStation(station_end)
        self.items = items
        self.uploading = False

    def write(self, data: bytes) -> None:
        self._rover_end.write(data)

    def read(self) -> bytes:
        received = self.station.receive()
        if not self.uploading and any(m.get_type() == "HEARTBEAT" for m in received):
            self.uploading = True
            self.station.send(mavlink2.MAVLink_mission_count_message(*ROVER, len(self.items), MISSION))
        self.station.answer(self.items, received)
        return self._rover_end.read()

    def close(self) -> None:
        self._rover_end.close()
