"""A mission: its items in order, waypoints driven one at a time (the next when guidance reports ARRIVED)
and speed changes (MAV_CMD_DO_CHANGE_SPEED) applied as the mission comes to them; a return to launch
(MAV_CMD_NAV_RETURN_TO_LAUNCH) is driven to home like a waypoint, and reached, the mission goes on to its
next item (complete when it was the last), as ArduPilot Rover's Auto mode drives RTL as a sub-mode. A jump
(MAV_CMD_DO_JUMP) is passed as a speed change is, in no time: the mission goes on at its target, its count
of times permitting, else past it; a delay (MAV_CMD_NAV_DELAY) is current while the onboard stack waits it
out, as a waypoint is while the rover drives to it.

Pure and clock-free: it holds the items (waypoints in local ENU metres, ``SpeedChange``,
``ReturnToLaunch``, ``Jump``, ``Delay``), which one is current and how many times each jump has been taken,
and says where to go next (a ``Leg``: the speed changes and jumps passed on the way, then the waypoint, the
return to launch or the delay; where home is, and the clock a delay counts on, are the onboard stack's).
The onboard stack (``navigator.onboard_mission``) hands guidance each waypoint as its goal and each speed
change as its speed limit, publishes the events and tells a ground station
(``firmware_bridge.mavlink_mission``). Items are numbered from 0 as uploaded, speed changes included, as
MAVLink numbers them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

from firmware_bridge.mavlink_home import ReturnToLaunch
from firmware_bridge.mavlink_mission import MissionStep
from firmware_bridge.mission_delay import Delay
from firmware_bridge.mission_jump import JUMP_FOREVER, Jump, idle_loop, idle_loop_reason, moves_the_rover
from firmware_bridge.mission_speed import SpeedChange
from firmware_bridge.mission_state import MissionState
from navigator.errors import ParameterError

__all__ = [
    "Delay",
    "DrivenItem",
    "Jump",
    "JumpPassed",
    "Leg",
    "Mission",
    "MissionState",
    "ReturnToLaunch",
    "SpeedChange",
    "Waypoint",
]


class Waypoint(NamedTuple):
    """Where to drive (local ENU metres), and how long to wait there before the next item (s;
    ``HOLD_UNLIMITED``: until the operator moves the mission on, a loiter without end)."""

    x: float
    y: float
    hold_s: float = 0.0


# An item as the mission drives it (``firmware_bridge.mavlink_mission.MissionItem`` is one as uploaded).
DrivenItem = Waypoint | SpeedChange | ReturnToLaunch | Jump | Delay


class JumpPassed(NamedTuple):
    """A jump the mission came to: item ``seq``, ``jump``; ``taken``: it went on at the target (the
    ``done``-th time of ``jump.repeat``), else past it, its count done."""

    seq: int
    jump: Jump
    done: int
    taken: bool


class Leg(NamedTuple):
    """Where the mission goes next: the speed changes it passed on the way (item number and change, in
    order; each applies at once), then the waypoint (or return to launch, or delay) now current, or None
    when none was left (the mission is COMPLETE); ``jumps``: the jumps passed on the way, in order."""

    speed_changes: tuple[tuple[int, SpeedChange], ...]
    target: Waypoint | ReturnToLaunch | Delay | None
    jumps: tuple[JumpPassed, ...] = ()


class Mission:
    """The mission in force and its progress.

    ``state`` and ``current`` are plain attributes (the control tick reads ``state`` every tick); change
    them only through the methods. ``current`` is the waypoint (or return to launch, or delay) being driven
    to or waited out (ACTIVE), the one a single goal interrupted (PAUSED), the last item or the return to
    launch the mission ended at (COMPLETE, ``end_here``), or 0 (NOT_STARTED: loaded, not driven yet). A
    speed change or a jump is current for no time: the mission passes it and goes on in the same call.

    Each jump counts the times it was taken in this run of the mission: from 0 on ``load`` and on a
    ``set_current`` that starts the mission again (``restart``), kept by one that goes on with it.
    """

    def __init__(self) -> None:
        self.items: tuple[DrivenItem, ...] = ()
        self.current = 0
        self.state = MissionState.NONE
        self._jumps_done: dict[int, int] = {}  # jump item -> times taken in this run

    @property
    def count(self) -> int:
        """How many items, speed changes included (MISSION_CURRENT's total)."""
        return len(self.items)

    @property
    def waypoints(self) -> tuple[Waypoint, ...]:
        """The waypoints alone, in order."""
        return tuple(item for item in self.items if isinstance(item, Waypoint))

    def load(self, items: Sequence[MissionStep]) -> None:
        """Replace the mission with ``items`` (waypoints as (x, y) or ``PlacedWaypoint`` with a hold time,
        speed changes, returns to launch, jumps, delays), NOT_STARTED: ``set_current`` drives it.

        ``ParameterError`` (the mission in force kept) for no waypoint or return to launch among them, a
        coordinate that is not a finite number, a hold time that is not a non-negative duration (infinite:
        a loiter without end), a delay that is not a finite one, a jump to an item the mission lacks or one
        whose loop has no item that moves the rover (``firmware_bridge.mission_jump.idle_loop``)."""
        loaded: list[DrivenItem] = []
        for index, item in enumerate(items):
            if isinstance(item, Jump):
                if not 0 <= item.target < len(items):
                    raise ParameterError(f"mission item {index}: {item} jumps nowhere in the mission")
                if item.repeat < JUMP_FOREVER:
                    raise ParameterError(
                        f"mission item {index}: {item} repeats {item.repeat} times "
                        "(0 or more, or -1: for ever)"
                    )
                loaded.append(item)
                continue
            if isinstance(item, Delay):
                if not 0.0 <= item.seconds < math.inf:  # NaN fails too
                    raise ParameterError(f"mission item {index}: delay {item.seconds} s is not a duration")
                loaded.append(item)
                continue
            if isinstance(item, SpeedChange | ReturnToLaunch):
                loaded.append(item)
                continue
            x, y, hold_s = item if len(item) == 3 else (*item, 0.0)  # (x, y) or a PlacedWaypoint
            if not (math.isfinite(x) and math.isfinite(y)):
                raise ParameterError(f"mission waypoint {index} ({x}, {y}) is not a finite position")
            if not hold_s >= 0.0:  # NaN fails too
                raise ParameterError(f"mission waypoint {index}: hold {hold_s} s is not a duration")
            loaded.append(Waypoint(float(x), float(y), float(hold_s)))
        if not any(moves_the_rover(item) for item in loaded):
            raise ParameterError("a mission needs at least one waypoint (or return to launch)")
        found = idle_loop(loaded)
        if found is not None:
            raise ParameterError(idle_loop_reason(*found))
        self.items = tuple(loaded)
        self.current = 0
        self.state = MissionState.NOT_STARTED
        self._jumps_done = {}

    def clear(self) -> bool:
        """Forget the mission; True if it was being driven."""
        was_active = self.state is MissionState.ACTIVE
        self.items = ()
        self.current = 0
        self.state = MissionState.NONE
        self._jumps_done = {}
        return was_active

    def pause(self) -> bool:
        """A single goal replaces the mission being driven: True if it was (it is PAUSED now)."""
        if self.state is not MissionState.ACTIVE:
            return False
        self.state = MissionState.PAUSED
        return True

    def set_current(self, seq: int, *, restart: bool = True) -> Leg:
        """Drive the mission from item ``seq`` (whatever its state): the speed changes and jumps from it up
        to the next waypoint (or return to launch, or delay), which becomes current. ``restart``: a new run
        of the mission, every jump's count from 0; else the counts go on (a resume). The speed the items
        before ``seq`` set is ``speed_set_before(seq)``'s. ``ParameterError`` if there is no mission or no
        such item."""
        if not self.items:
            raise ParameterError(f"no mission: item {seq} cannot be made current")
        if not 0 <= seq < len(self.items):
            raise ParameterError(f"item {seq} is not in the mission (items 0..{len(self.items) - 1})")
        if restart:
            self._jumps_done = {}
        self.state = MissionState.ACTIVE
        return self._go_from(seq)

    def jumps_done(self, seq: int) -> int:
        """How many times the jump at item ``seq`` was taken in this run (0 for any other item)."""
        return self._jumps_done.get(seq, 0)

    def speed_set_before(self, seq: int) -> tuple[int, SpeedChange] | None:
        """The last speed change before item ``seq`` that set or reset the speed (item number and change;
        "no change" items skipped), or None: the speed a mission driven from its start would have when it
        came to ``seq``. A mission started part-way applies it, as PX4 replays the last speed change
        before the item it resumes at: a "slow zone" stays slow however the ground station jumps into it.
        A return to launch before ``seq`` ends the search (None): it drives at the rover's own speed and
        lifts the limit (``navigator.onboard_mission``), so no speed change before it stands after it."""
        for index in range(min(seq, len(self.items)) - 1, -1, -1):
            item = self.items[index]
            if isinstance(item, ReturnToLaunch):
                return None
            if isinstance(item, SpeedChange) and not item.keep:
                return index, item
        return None

    def reached(self) -> Leg:
        """The current waypoint was reached: the speed changes after it up to the next waypoint (now
        current), or to the end (the mission is COMPLETE). A return to launch reached goes on the same
        way: ArduPilot Rover's ``ModeAuto::verify_RTL`` returns ``reached_destination()``, so its mission
        goes on to the item after RTL once home is reached. ``ParameterError`` unless the mission is
        ACTIVE."""
        if self.state is not MissionState.ACTIVE:
            raise ParameterError(f"no mission is being driven (mission {self.state.value})")
        return self._go_from(self.current + 1)

    def end_here(self) -> None:
        """The current item cannot be driven (a return to launch with no home to go to): the mission ends
        COMPLETE on it, ``current`` kept, whatever items follow. ``ParameterError`` unless ACTIVE."""
        if self.state is not MissionState.ACTIVE:
            raise ParameterError(f"no mission is being driven (mission {self.state.value})")
        self.state = MissionState.COMPLETE

    def current_waypoint(self) -> Waypoint:
        """The waypoint being driven to (or interrupted, or reached last); ``ParameterError`` when the
        current item is none (no mission; a mission complete after a speed change)."""
        item = self.items[self.current] if self.current < len(self.items) else None
        if not isinstance(item, Waypoint):
            raise ParameterError(
                f"item {self.current} of the mission (mission {self.state.value}) is no waypoint"
            )
        return item

    def _go_from(self, seq: int) -> Leg:
        """From item ``seq`` on: the speed changes and jumps passed, then the first waypoint, return to
        launch or delay, made current.

        ``load`` refuses a loop without an item that moves the rover, so the walk passes each item at most
        once (a jump taken leads to such an item before the jump again) and ends within ``count`` steps.
        The bound is kept here too: should an idle loop ever get in, the walk ends the mission COMPLETE
        rather than spin the control tick."""
        items = self.items
        changes: list[tuple[int, SpeedChange]] = []
        jumps: list[JumpPassed] = []
        index = seq
        for _ in range(len(items) + 1):
            if index >= len(items):
                break
            item = items[index]
            if isinstance(item, SpeedChange):
                changes.append((index, item))
                index += 1
            elif isinstance(item, Jump):
                done = self._jumps_done.get(index, 0)
                taken = item.repeat == JUMP_FOREVER or done < item.repeat
                if taken:
                    done = self._jumps_done[index] = done + 1
                jumps.append(JumpPassed(index, item, done, taken))
                index = item.target if taken else index + 1
            else:
                self.current = index
                return Leg(tuple(changes), item, tuple(jumps))
        self.current = len(items) - 1
        self.state = MissionState.COMPLETE
        return Leg(tuple(changes), None, tuple(jumps))
