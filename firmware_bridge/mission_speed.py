"""MAV_CMD_DO_CHANGE_SPEED (178) as a mission item, as the rover reads it
(https://mavlink.io/en/messages/common.html#MAV_CMD_DO_CHANGE_SPEED).

Defined here, below both the MAVLink mission server (``firmware_bridge.mavlink_mission``), which judges an
uploaded item, and the mission the navigator drives (``navigator.mission``), which applies it: ``navigator``
imports ``firmware_bridge``, never the other way round (docs/ARCHITECTURE.md).

* param1, the speed type: 0 (airspeed) or 1 (ground speed), both taken as ground speed, as ArduPilot Rover
  takes them. Anything else (2 climb and 3 descent speed, which mean nothing on the ground, a number that is
  no speed type) is refused with ``MAV_MISSION_INVALID_PARAM1``.
* param2, the speed in m/s: above 0 and finite, the rover's speed limit from that item on; -1 no change; -2
  back to the default (no limit of the mission's). Anything else (0, which would park the rover mid-mission
  with nothing to say why, other negative numbers, NaN, infinity) is refused with
  ``MAV_MISSION_INVALID_PARAM2``, and so is a speed below the slowest the rover drives with its stuck and
  stall failsafes awake (``slowest_mission_speed``: 0.2 m/s with the default config). A speed above
  ``[follower] max_speed_mps`` is accepted: the limit only ever lowers the target speed, so the rover's own
  maximum stands (a plan made for a faster vehicle, or with a ground station's default cruise speed, drives
  as fast as this rover may, not refused whole).
* param3 (throttle) and param4 are not used; with the frame, position and ``autocontinue`` they are kept
  for a download. The item has no position: any frame is taken.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

SPEED_NO_CHANGE = -1.0  # param2: the speed in force stays
SPEED_DEFAULT = -2.0  # param2: back to the vehicle's default speed
# param1: SPEED_TYPE_AIRSPEED, SPEED_TYPE_GROUNDSPEED; a rover has only a ground speed.
SPEED_TYPES = (float(mavlink2.SPEED_TYPE_AIRSPEED), float(mavlink2.SPEED_TYPE_GROUNDSPEED))


@dataclass(frozen=True)
class SpeedChange:
    """A DO_CHANGE_SPEED item as the rover applies it: what becomes of the mission's speed limit.

    ``limit_mps``: the limit from this item on (m/s, > 0), or None for none of the mission's (param2 -2,
    back to the default); ``keep``: param2 -1, the limit in force stays (``limit_mps`` is None then)."""

    limit_mps: float | None
    keep: bool = False


def speed_change_refusal(
    seq: int, param1: float, param2: float, slowest_mps: float = 0.0
) -> tuple[int, str] | None:
    """Why a DO_CHANGE_SPEED item cannot be taken (the MISSION_ACK result and the reason), or None.

    ``slowest_mps``: the lowest speed the rover takes (``slowest_mission_speed``); a speed below it is
    refused."""
    if param1 not in SPEED_TYPES:
        return (
            mavlink2.MAV_MISSION_INVALID_PARAM1,
            f"item {seq}: DO_CHANGE_SPEED speed type (param1) {param1} is not taken: only 0 (airspeed) or 1 "
            "(ground speed), both read as ground speed",
        )
    if param2 in (SPEED_NO_CHANGE, SPEED_DEFAULT):
        return None
    if math.isfinite(param2) and param2 > 0.0:
        if param2 >= slowest_mps:
            return None
        return (
            mavlink2.MAV_MISSION_INVALID_PARAM2,
            f"item {seq}: DO_CHANGE_SPEED speed (param2) {param2:g} m/s is below {slowest_mps:g} m/s, the "
            "slowest this rover drives with its stuck and stall checks awake",
        )
    return (
        mavlink2.MAV_MISSION_INVALID_PARAM2,
        f"item {seq}: DO_CHANGE_SPEED speed (param2) {param2} m/s is not a speed: above 0, or -1 (no "
        "change), or -2 (back to the default)",
    )


def speed_change(param2: float) -> SpeedChange:
    """The change an item with speed ``param2`` makes (one ``speed_change_refusal`` took)."""
    if param2 == SPEED_NO_CHANGE:
        return SpeedChange(None, keep=True)
    if param2 == SPEED_DEFAULT:
        return SpeedChange(None)
    return SpeedChange(float(param2))


def slowest_mission_speed(
    min_speed_mps: float, stuck_min_command_mps: float, stall_min_command_mps: float
) -> float:
    """The lowest speed a mission may set: the follower's creep speed (``[follower] min_speed_mps``, the
    slowest it approaches a goal), and the commanded speeds above which the safety supervisor watches
    for a rover that does not move (``[safety] stuck_min_command_mps``) and a wheel that does not turn
    (``wheel_stall_min_command_mps``). Below those a stuck rover would sit showing DRIVING with no
    failsafe, and a mission speed near 0 would park it mid-mission with nothing to say why."""
    return max(min_speed_mps, stuck_min_command_mps, stall_min_command_mps)
