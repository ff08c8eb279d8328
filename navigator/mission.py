"""A mission: its items in order, waypoints driven one at a time (the next when guidance reports ARRIVED)
and speed changes (MAV_CMD_DO_CHANGE_SPEED) applied as the mission comes to them; a return to launch
(MAV_CMD_NAV_RETURN_TO_LAUNCH) is driven to home like a waypoint, and reached, the mission goes on to its
next item (complete when it was the last), as ArduPilot Rover's Auto mode drives RTL as a sub-mode.

Pure and clock-free: it holds the items (waypoints in local ENU metres, ``SpeedChange``,
``ReturnToLaunch``) and which one is current, and says where to go next (a ``Leg``: the speed changes
passed on the way, then the waypoint or the return to launch; where home is, is the onboard stack's).
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
from firmware_bridge.mission_speed import SpeedChange
from firmware_bridge.mission_state import MissionState
from navigator.errors import ParameterError

__all__ = ["DrivenItem", "Leg", "Mission", "MissionState", "ReturnToLaunch", "SpeedChange", "Waypoint"]


class Waypoint(NamedTuple):
    """Where to drive (local ENU metres), and how long to wait there before the next item (s;
    ``HOLD_UNLIMITED``: until the operator moves the mission on, a loiter without end)."""

    x: float
    y: float
    hold_s: float = 0.0


# An item as the mission drives it (``firmware_bridge.mavlink_mission.MissionItem`` is one as uploaded).
DrivenItem = Waypoint | SpeedChange | ReturnToLaunch
# The items the rover drives to (a mission needs one).
_DRIVEN = (Waypoint, ReturnToLaunch)


class Leg(NamedTuple):
    """Where the mission goes next: the speed changes it passed on the way (item number and change, in
    order; each applies at once), then the waypoint (or return to launch) now current, or None when none
    was left (the mission is COMPLETE)."""

    speed_changes: tuple[tuple[int, SpeedChange], ...]
    target: Waypoint | ReturnToLaunch | None


class Mission:
    """The mission in force and its progress.

    ``state`` and ``current`` are plain attributes (the control tick reads ``state`` every tick); change
    them only through the methods. ``current`` is the waypoint (or return to launch) being driven to
    (ACTIVE), the one a single goal interrupted (PAUSED), the last item or the return to launch the
    mission ended at (COMPLETE, ``end_here``), or 0 (NOT_STARTED: loaded, not driven yet). A speed
    change is current for no time: the mission applies it and goes on in the same call.
    """

    def __init__(self) -> None:
        self.items: tuple[DrivenItem, ...] = ()
        self.current = 0
        self.state = MissionState.NONE

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
        speed changes, returns to launch), NOT_STARTED: ``set_current`` drives it.

        ``ParameterError`` (the mission in force kept) for no waypoint or return to launch among them, a
        coordinate that is not a finite number or a hold time that is not a non-negative duration
        (infinite: a loiter without end)."""
        loaded: list[DrivenItem] = []
        for index, item in enumerate(items):
            if isinstance(item, SpeedChange | ReturnToLaunch):
                loaded.append(item)
                continue
            x, y, hold_s = item if len(item) == 3 else (*item, 0.0)  # (x, y) or a PlacedWaypoint
            if not (math.isfinite(x) and math.isfinite(y)):
                raise ParameterError(f"mission waypoint {index} ({x}, {y}) is not a finite position")
            if not hold_s >= 0.0:  # NaN fails too
                raise ParameterError(f"mission waypoint {index}: hold {hold_s} s is not a duration")
            loaded.append(Waypoint(float(x), float(y), float(hold_s)))
        if not any(isinstance(item, _DRIVEN) for item in loaded):
            raise ParameterError("a mission needs at least one waypoint (or return to launch)")
        self.items = tuple(loaded)
        self.current = 0
        self.state = MissionState.NOT_STARTED

    def clear(self) -> bool:
        """Forget the mission; True if it was being driven."""
        was_active = self.state is MissionState.ACTIVE
        self.items = ()
        self.current = 0
        self.state = MissionState.NONE
        return was_active

    def pause(self) -> bool:
        """A single goal replaces the mission being driven: True if it was (it is PAUSED now)."""
        if self.state is not MissionState.ACTIVE:
            return False
        self.state = MissionState.PAUSED
        return True

    def set_current(self, seq: int) -> Leg:
        """Drive the mission from item ``seq`` (whatever its state): the speed changes from it up to the
        next waypoint, which becomes current. The speed the items before ``seq`` set is
        ``speed_set_before(seq)``'s. ``ParameterError`` if there is no mission or no such item."""
        if not self.items:
            raise ParameterError(f"no mission: item {seq} cannot be made current")
        if not 0 <= seq < len(self.items):
            raise ParameterError(f"item {seq} is not in the mission (items 0..{len(self.items) - 1})")
        self.state = MissionState.ACTIVE
        return self._go_from(seq)

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
        """From item ``seq`` on: the speed changes passed, then the first waypoint or return to launch,
        made current."""
        items = self.items
        changes: list[tuple[int, SpeedChange]] = []
        for index in range(seq, len(items)):
            item = items[index]
            if not isinstance(item, SpeedChange):
                self.current = index
                return Leg(tuple(changes), item)
            changes.append((index, item))
        self.current = len(items) - 1
        self.state = MissionState.COMPLETE
        return Leg(tuple(changes), None)
