"""A MAV_CMD_NAV_WAYPOINT's hold time (param1): how long the rover waits at the waypoint before the next.

ArduPilot Rover reads a waypoint's param1 as a delay in seconds at the waypoint, PX4 as its hold time; a
survey rover stops at each waypoint to take its sample. The spec gives it in seconds, at least 0
(https://mavlink.io/en/messages/common.html#MAV_CMD_NAV_WAYPOINT). Read here, below both the mission
server (``firmware_bridge.mavlink_mission``), which judges an uploaded item, and the mission the navigator
drives (``navigator.mission``):

* 0 (QGroundControl's default), or NaN, MAVLink's "no value" for a parameter a sender leaves unset: no hold.
* A finite number of seconds up to ``MAX_HOLD_S``: the hold.
* Anything else (negative, infinite, beyond an hour): refused with ``MAV_MISSION_INVALID_PARAM1``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from pymavlink.dialects.v20 import common as mavlink2

# An hour: longer is no hold a rover's mission means (a ground station's typo in minutes or ms), and the
# rover would sit showing its mission as ACTIVE with nothing to say why.
MAX_HOLD_S = 3600.0


class PlacedWaypoint(NamedTuple):
    """A waypoint as the rover drives it: local ENU metres, and the seconds it waits there."""

    x: float
    y: float
    hold_s: float = 0.0


def hold_refusal(seq: int, param1: float) -> tuple[int, str] | None:
    """Why a waypoint's hold time cannot be taken (the MISSION_ACK result and the reason), or None."""
    if math.isnan(param1) or 0.0 <= param1 <= MAX_HOLD_S:
        return None
    return (
        mavlink2.MAV_MISSION_INVALID_PARAM1,
        f"item {seq}: MAV_CMD_NAV_WAYPOINT hold time (param1) {param1} s is not a hold: 0 to "
        f"{MAX_HOLD_S:g} s (0 or NaN: none)",
    )


def hold_seconds(param1: float) -> float:
    """The hold a waypoint's param1 asks for (one ``hold_refusal`` took): NaN is none."""
    return 0.0 if math.isnan(param1) else float(param1)
