"""MAV_CMD_NAV_DELAY (93) as a mission item, as the rover reads it
(https://mavlink.io/en/messages/common.html#MAV_CMD_NAV_DELAY).

Defined here, below both the MAVLink mission server (``firmware_bridge.mavlink_mission``), which judges an
uploaded item, and the mission the navigator drives (``navigator.mission``), which waits it out.

* param1, the delay in seconds: 0 to ``MAX_HOLD_S`` (an hour, as a waypoint's hold: longer is a ground
  station's typo, and the rover would sit ACTIVE with nothing to say why), counted on the stack's clock
  from when the mission comes to the item (simulated in lockstep, monotonic on the rover), the rover held
  where it is. Anything else (NaN, infinity, negative) is refused with ``MAV_MISSION_INVALID_PARAM1``.
* param1 = -1 with an hour, minute and second of the day (UTC) in params 2-4, "until that time of day", is
  refused with ``MAV_MISSION_INVALID_PARAM1`` saying so: the stack's clock is monotonic (simulated in a
  lockstep trial) and carries no time of day, so the rover has nothing trustworthy to wait for it on.
* params 2-4 otherwise, the frame, position and ``autocontinue`` are kept for a download, not used. The item
  has no position: any frame is taken.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mission_hold import MAX_HOLD_S

DELAY_TIME_OF_DAY = -1.0  # param1: wait until the time of day in params 2-4 (not taken)


class Delay(NamedTuple):
    """A NAV_DELAY item as the mission waits it out: seconds, the rover held where it is."""

    seconds: float


def delay_refusal(seq: int, param1: float) -> tuple[int, str] | None:
    """Why a NAV_DELAY item cannot be taken (the MISSION_ACK result and the reason), or None."""
    if param1 == DELAY_TIME_OF_DAY:
        return (
            mavlink2.MAV_MISSION_INVALID_PARAM1,
            f"item {seq}: NAV_DELAY delay (param1) -1, until a time of day (params 2-4), is not taken: the "
            "rover's clock has no time of day; give the delay in seconds",
        )
    if math.isfinite(param1) and 0.0 <= param1 <= MAX_HOLD_S:
        return None
    return (
        mavlink2.MAV_MISSION_INVALID_PARAM1,
        f"item {seq}: NAV_DELAY delay (param1) {param1} s is not a delay: 0 to {MAX_HOLD_S:g} s",
    )


def delay(param1: float) -> Delay:
    """The wait an item asks for (one ``delay_refusal`` took)."""
    return Delay(float(param1))
