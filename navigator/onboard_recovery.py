"""When a rover held for no progress recovers (``navigator.recovery``), and when it holds for the operator.

The stack asks on every tick the ``no_progress`` failsafe holds the rover and learning its ground's traction
(``navigator.climb_learning``, first: where it applies it explains the hold) did not clear it. It recovers
when ``[planner] recover_when_stuck`` is on, guidance was ``DRIVING`` (not stopped or backing off for a
moving obstacle: ``BLOCKED`` / ``YIELDING``), no tip-over margin is breached, the footprint just behind is
clear of the believed map (else it could not back out: it does not move), the spot it dug in on is not at
the goal (a mark there would make the goal unreachable), and fewer than ``recovery_attempts`` recoveries
were made since the last goal given or resume (counted as the learning counts,
``SafetySupervisor.goals_given``: a goal, a mission started or an item made current, not a mission
advancing by itself to its next waypoint, as for the ``stuck`` latch: a rover that digs in on the way to
one waypoint digs in on the way to the next).
Otherwise it holds, latched, for the operator as before; ``recovery.gave_up`` says why, once per hold.
"""

from __future__ import annotations

import math

from estimator.pose import PoseEstimate
from navigator.config import RoverConfig
from navigator.footprint import Footprint
from navigator.recovery import dig_in_mark, mark_covers
from navigator.route_guidance import Mode, RouteGuidance
from navigator.safety import NO_PROGRESS, TIP_OVER, EventSink, SafetySupervisor
from navigator.yielding import way_blocked


class DigInRecovery:
    """Decides, per hold, whether the rover backs out and plans round the spot, or holds (module doc)."""

    def __init__(
        self, config: RoverConfig, route: RouteGuidance, safety: SafetySupervisor, event: EventSink
    ) -> None:
        planner = config.planner
        self._enabled = planner.recover_when_stuck
        self._attempts = planner.recovery_attempts
        self._back_m = planner.recovery_back_m
        self._back_speed_mps = planner.yield_speed_mps  # 0: backing off (and out) is turned off
        self._vehicle = config.vehicle
        self._footprint = Footprint.of(config.vehicle)
        self._fence = config.safety.fence
        # The planner keeps the rover's centre this far from any obstacle (footprint circle and inflation).
        self._clearance_m = config.vehicle.footprint_radius_m + planner.inflation_m
        self._route = route
        self._safety = safety
        self._event = event
        self._counted_at_goal = 0  # SafetySupervisor.goals_given when the count below began
        self._recoveries = 0
        self._told_gave_up = False  # recovery.gave_up said for the hold in force
        self._marks = 0  # marks made so far this run: their ids count on

    def consider(self, now: int, pose: PoseEstimate | None, faults: tuple[str, ...]) -> None:
        """Held for ``no_progress`` at ``now``: recover, or hold (told once per hold)."""
        route, safety = self._route, self._safety
        if not self._enabled:
            return
        if safety.goals_given != self._counted_at_goal:
            self._counted_at_goal, self._recoveries, self._told_gave_up = safety.goals_given, 0, False
        goal = route.goal
        if pose is None or goal is None or route.mode is not Mode.DRIVING or TIP_OVER in faults:
            return  # stopped or backing off for a mover, or tipping: not a dig-in to back out of (yet)
        if self._told_gave_up:
            return
        at = (pose.x, pose.y, pose.yaw)
        if self._recoveries >= self._attempts:
            self._give_up(
                f"{self._recoveries} recoveries since the last goal given or resume, the limit "
                "([planner] recovery_attempts)"
            )
            return
        mark = dig_in_mark(now, at, self._vehicle, self._marks + 1)
        if mark_covers(mark, (goal.x, goal.y), self._clearance_m):
            self._give_up(
                f"dug in at the goal ({goal.x:.2f}, {goal.y:.2f}): a mark there would make it unreachable"
            )
            return
        if self._back_speed_mps <= 0.0:
            self._give_up("no backing out: [planner] yield_speed_mps is 0")
            return
        blocked = way_blocked(route.planner.terrain, at, self._footprint, -1.0, self._fence)
        if blocked:
            self._give_up(f"no clear way back: {blocked} behind")
            return
        self._recoveries += 1
        self._marks += 1
        why = safety.fault_detail(NO_PROGRESS) or "no progress"
        self._event(
            "recovery.backing_out",
            "warning",
            f"dug in at ({pose.x:.2f}, {pose.y:.2f}) heading {math.degrees(pose.yaw):.0f} deg ({why}): "
            f"backing out up to {self._back_m:g} m, then marking the spot as {mark.obstacle_id} and planning "
            f"round it (recovery {self._recoveries} of {self._attempts} since the last goal given or resume)",
        )
        route.recover(now, pose, mark)
        safety.progress_recovering(f"backing out to plan round where it dug in ({mark.obstacle_id})")

    def _give_up(self, why: str) -> None:
        self._told_gave_up = True
        self._event("recovery.gave_up", "error", f"{why}; holding for the operator (resume or a new goal)")
