"""A MAV_CMD_NAV_WAYPOINT's hold time (param1): how long the rover waits at the waypoint before the next.

ArduPilot Rover reads a waypoint's param1 as a delay in seconds at the waypoint, PX4 as its hold time; a
survey rover stops at each waypoint to take its sample. The spec gives it in seconds, at least 0
(https://mavlink.io/en/messages/common.html#MAV_CMD_NAV_WAYPOINT). Read here, below both the mission
server (``firmware_bridge.mavlink_mission``), which judges an uploaded item, and the mission the navigator
drives (``navigator.mission``):

* 0 (QGroundControl's default), or NaN, MAVLink's "no value" for a parameter a sender leaves unset: no hold.
* A finite number of seconds up to ``MAX_HOLD_S``: the hold.
* Anything else (negative, infinite, beyond an hour): refused with ``MAV_MISSION_INVALID_PARAM1``.

The loiter items are waypoints with a hold, the same mechanism: MAV_CMD_NAV_LOITER_TIME's param1 is its
loiter time, judged as a hold time except that NaN is refused (the time is what the item is for; a sender
that leaves it unset means a plain waypoint, and should send one); MAV_CMD_NAV_LOITER_UNLIM holds for ever
(``HOLD_UNLIMITED``): the mission goes on only when the operator moves it (a current item set, a start, a
clear, a new goal or mission). The rover stops at the point; the rest is kept for a download, not used:
the loiter radius (param3) of both, LOITER_TIME's heading required (param2) and Xtrack location (param4),
LOITER_UNLIM's yaw (param4).
"""

from __future__ import annotations

import math
from typing import NamedTuple

from pymavlink.dialects.v20 import common as mavlink2

# An hour: longer is no hold a rover's mission means (a ground station's typo in minutes or ms), and the
# rover would sit showing its mission as ACTIVE with nothing to say why.
MAX_HOLD_S = 3600.0
HOLD_UNLIMITED = math.inf  # MAV_CMD_NAV_LOITER_UNLIM: until the operator moves the mission on


class PlacedWaypoint(NamedTuple):
    """A waypoint as the rover drives it: local ENU metres, and the seconds it waits there
    (``HOLD_UNLIMITED``: until moved on)."""

    x: float
    y: float
    hold_s: float = 0.0


def hold_refusal(
    seq: int, param1: float, what: str = "MAV_CMD_NAV_WAYPOINT hold time", *, unset_is_none: bool = True
) -> tuple[int, str] | None:
    """Why a hold time cannot be taken (the MISSION_ACK result and the reason), or None. ``what`` names
    the param in the reason; ``unset_is_none``: NaN is no hold (a waypoint's), else refused (a loiter
    time's)."""
    if (unset_is_none and math.isnan(param1)) or 0.0 <= param1 <= MAX_HOLD_S:
        return None
    unset = "0 or NaN: none" if unset_is_none else "0: none"
    return (
        mavlink2.MAV_MISSION_INVALID_PARAM1,
        f"item {seq}: {what} (param1) {param1} s is not a hold: 0 to {MAX_HOLD_S:g} s ({unset})",
    )


def hold_seconds(param1: float) -> float:
    """The hold a waypoint's param1 asks for (one ``hold_refusal`` took): NaN is none."""
    return 0.0 if math.isnan(param1) else float(param1)
