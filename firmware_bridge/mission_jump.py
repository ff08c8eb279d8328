"""MAV_CMD_DO_JUMP (177) as a mission item, as the rover reads it
(https://mavlink.io/en/messages/common.html#MAV_CMD_DO_JUMP; ArduPilot's "Mission Command List": DO_JUMP).

Defined here, below both the MAVLink mission server (``firmware_bridge.mavlink_mission``), which judges an
uploaded item and the mission it ends, and the mission the navigator drives (``navigator.mission``), which
takes the jumps: ``navigator`` imports ``firmware_bridge``, never the other way round.

* param1, the item to go on at: a whole number, an item of the mission (numbered from 0 as uploaded, as
  every item here is). Anything else (NaN, a fraction, negative, past the last item) is refused with
  ``MAV_MISSION_INVALID_PARAM1``.
* param2, the repeat count: how many times in all the mission jumps there (a two-waypoint loop jumped twice
  drives A B A B A B, then the item after the jump); 0 never jumps; -1 for ever (ArduPilot's
  ``AP_MISSION_JUMP_REPEAT_FOREVER``). Anything else (NaN, a fraction, infinity, negative other than -1)
  is refused with ``MAV_MISSION_INVALID_PARAM2``.
* A jump whose loop the mission could go round without an item that moves the rover (a waypoint, a
  loiter, a return to launch) is refused with ``MAV_MISSION_INVALID_PARAM1`` (``idle_loop``): a jump to
  itself, two jumps to each other, a jump back over speed changes or delays alone. Such a loop would spin
  the control tick (a speed change, a jump is passed in no time) or hold the rover in place for ever.
* param3 and param4 are not used; with the frame, position and ``autocontinue`` they are kept for a
  download. The item has no position: any frame is taken.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mission_delay import Delay
from firmware_bridge.mission_speed import SpeedChange

JUMP_FOREVER = -1  # param2: jump every time the mission comes to the item


class Jump(NamedTuple):
    """A DO_JUMP item as the mission takes it: go on at item ``target``, ``repeat`` times in all
    (``JUMP_FOREVER``: every time), then past the jump."""

    target: int
    repeat: int


def jump_refusal(seq: int, param1: float, param2: float, count: int) -> tuple[int, str] | None:
    """Why a DO_JUMP item of a mission of ``count`` items cannot be taken (the MISSION_ACK result and the
    reason), or None. Its loop is judged once the whole mission is known (``idle_loop``)."""
    if not (_whole(param1) and 0 <= param1 < count):
        return (
            mavlink2.MAV_MISSION_INVALID_PARAM1,
            f"item {seq}: DO_JUMP target (param1) {param1} is not an item of the mission: a whole number "
            f"0..{count - 1}",
        )
    if not (_whole(param2) and param2 >= JUMP_FOREVER):
        return (
            mavlink2.MAV_MISSION_INVALID_PARAM2,
            f"item {seq}: DO_JUMP repeat count (param2) {param2} is not a count: a whole number 0 or more, "
            "or -1 (for ever)",
        )
    return None


def jump(param1: float, param2: float) -> Jump:
    """The jump an item makes (one ``jump_refusal`` took)."""
    return Jump(int(param1), int(param2))


def moves_the_rover(step: object) -> bool:
    """Whether a mission item (as the server or the navigator holds it) is one the rover drives to: a
    waypoint, a loiter, a return to launch; not a speed change, a jump or a delay."""
    return not isinstance(step, SpeedChange | Jump | Delay)


def idle_loop(steps: Sequence[object]) -> tuple[int, Jump] | None:
    """The first jump (item number and jump) whose loop the mission can go round without coming to an item
    that moves the rover (``moves_the_rover``), or None when every loop has one.

    The mission stops walking at an item that moves the rover; it passes every other item on to the next
    (a jump: to its target, or, its count done, past it). A loop must close with a jump back (``target``
    at or before the jump): it is idle when the walk from its target, taking every branch a jump may take,
    can come to the jump again without an item that moves the rover. Counts are not followed (a loop idle
    once is idle every time round). At most ``len(steps)`` squared steps: a mission has at most 256
    items."""
    count = len(steps)
    for seq, step in enumerate(steps):
        if not isinstance(step, Jump) or step.repeat == 0 or step.target > seq:
            continue
        seen: set[int] = set()
        waiting = [step.target]
        while waiting:
            index = waiting.pop()
            if index == seq:
                return seq, step
            if index >= count or index in seen or moves_the_rover(steps[index]):
                continue
            seen.add(index)
            here = steps[index]
            waiting.append(index + 1)
            if isinstance(here, Jump) and here.repeat != 0:
                waiting.append(here.target)
    return None


def idle_loop_reason(seq: int, found: Jump) -> str:
    """The refusal's reason for the jump ``idle_loop`` found at item ``seq``."""
    return (
        f"item {seq}: DO_JUMP target (param1) {found.target}: the loop from item {found.target} back to item "
        f"{seq} has no waypoint, loiter or return to launch: the mission would go round it without moving"
    )


def _whole(value: float) -> bool:
    """A finite whole number (NaN, infinity and fractions are not)."""
    return math.isfinite(value) and float(value).is_integer()
