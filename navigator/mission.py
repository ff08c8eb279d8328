"""A mission: waypoints driven in order, one at a time, the next one when guidance reports ARRIVED.

Pure and clock-free: it holds the waypoints (local ENU metres) and which one is current, and says which
one to drive to next. The onboard stack (``navigator.onboard_mission``) hands guidance each waypoint as
its goal, publishes the events and tells a ground station (``firmware_bridge.mavlink_mission``). Items are
numbered from 0, as MAVLink numbers them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

from firmware_bridge.mission_state import MissionState
from navigator.errors import ParameterError

__all__ = ["Mission", "MissionState", "Waypoint"]


class Waypoint(NamedTuple):
    x: float
    y: float


class Mission:
    """The mission in force and its progress.

    ``state`` and ``current`` are plain attributes (the control tick reads ``state`` every tick); change
    them only through the methods. ``current`` is the item being driven to (ACTIVE), the one a single goal
    interrupted (PAUSED), the last one (COMPLETE), or 0 (NOT_STARTED: loaded, not driven yet).
    """

    def __init__(self) -> None:
        self.waypoints: tuple[Waypoint, ...] = ()
        self.current = 0
        self.state = MissionState.NONE

    @property
    def count(self) -> int:
        return len(self.waypoints)

    def load(self, waypoints: Sequence[tuple[float, float]]) -> None:
        """Replace the mission with ``waypoints``, NOT_STARTED: ``set_current`` drives it.

        ``ParameterError`` (the mission in force kept) for an empty list or a coordinate that is not a
        finite number."""
        if not waypoints:
            raise ParameterError("a mission needs at least one waypoint")
        loaded = []
        for index, (x, y) in enumerate(waypoints):
            if not (math.isfinite(x) and math.isfinite(y)):
                raise ParameterError(f"mission waypoint {index} ({x}, {y}) is not a finite position")
            loaded.append(Waypoint(float(x), float(y)))
        self.waypoints = tuple(loaded)
        self.current = 0
        self.state = MissionState.NOT_STARTED

    def clear(self) -> bool:
        """Forget the mission; True if it was being driven."""
        was_active = self.state is MissionState.ACTIVE
        self.waypoints = ()
        self.current = 0
        self.state = MissionState.NONE
        return was_active

    def pause(self) -> bool:
        """A single goal replaces the mission being driven: True if it was (it is PAUSED now)."""
        if self.state is not MissionState.ACTIVE:
            return False
        self.state = MissionState.PAUSED
        return True

    def set_current(self, seq: int) -> Waypoint:
        """Make item ``seq`` current and drive the mission from it (whatever its state): returns it.
        ``ParameterError`` if there is no mission or no such item."""
        if not self.waypoints:
            raise ParameterError(f"no mission: item {seq} cannot be made current")
        if not 0 <= seq < len(self.waypoints):
            raise ParameterError(f"item {seq} is not in the mission (items 0..{len(self.waypoints) - 1})")
        self.current = seq
        self.state = MissionState.ACTIVE
        return self.waypoints[seq]

    def reached(self) -> Waypoint | None:
        """The current item was reached: returns the next to drive to (now current), or None when it was
        the last (the mission is COMPLETE). ``ParameterError`` unless the mission is ACTIVE."""
        if self.state is not MissionState.ACTIVE:
            raise ParameterError(f"no mission is being driven (mission {self.state.value})")
        if self.current + 1 >= len(self.waypoints):
            self.state = MissionState.COMPLETE
            return None
        self.current += 1
        return self.waypoints[self.current]
