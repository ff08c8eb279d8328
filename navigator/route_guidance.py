"""Guidance behind a start-up gate: a goal is held until the start-up checks pass, then planned and driven.

``RouteGuidance`` wraps ``navigator.guidance.Guidance`` (plan on a new goal, repair the plan as obstacles are
perceived, follow the path) for the onboard stack (``navigator.onboard``): the first plan must start from a
settled estimate, and ``Guidance`` itself does not know about readiness. ``Mode`` is guidance's mode as the
stack reports it (``navigator/state``'s ``mode``); ``GuidanceCommand`` the command while it does not drive.
"""

from __future__ import annotations

import enum
from concurrent.futures import Executor
from dataclasses import dataclass

from estimator.pose import PoseEstimate
from logs import topics
from logs.sink import MessageSink
from navigator.config import RoverConfig
from navigator.guidance import Guidance, GuidanceOutput
from navigator.perception import ObstacleObservation, obstacles_record
from navigator.planner import Path, Planner
from navigator.safety import EventSink
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TerrainClass


class Mode(enum.StrEnum):
    """Guidance's mode (what it is trying to do); the safety supervisor's mode is ``SafetyMode``."""

    IDLE = "IDLE"  # no goal
    WAITING_ESTIMATE = "WAITING_ESTIMATE"  # goal set, start-up checks not yet passed
    PLANNING = "PLANNING"  # the first plan to the goal is being made off the control thread (wheels held)
    DRIVING = "DRIVING"
    ARRIVED = "ARRIVED"
    NO_PATH = "NO_PATH"  # the planner proved the goal unreachable
    BLOCKED = "BLOCKED"  # stopped: a moving obstacle is predicted on the path
    YIELDING = "YIELDING"  # backing off slowly: a moving obstacle is predicted to reach the rover itself
    RECOVERING = "RECOVERING"  # dug in: backing out the way it came, to mark the spot and plan round it


# Guidance's mode names -> Mode, looked up every tick (a dict, not the enum's slower call).
_MODE_OF = {mode.value: mode for mode in Mode}


@dataclass(frozen=True)
class Goal:
    x: float
    y: float


@dataclass(frozen=True)
class GuidanceCommand:
    speed_mps: float
    yaw_rate_rps: float
    cross_track_error_m: float = 0.0
    speed_limit_mps: float = 0.0
    speed_limit_reason: str = "stopped"


STOPPED = GuidanceCommand(0.0, 0.0)


class RouteGuidance:
    """Holds a goal until the start-up checks pass, then lets ``Guidance`` plan, repair and follow.

    The gate is the only thing added here: the first plan must start from a settled estimate, and
    ``Guidance`` itself does not know about readiness.
    """

    def __init__(
        self,
        config: RoverConfig,
        terrain: TerrainMap,
        sink: MessageSink,
        event: EventSink,
        planning: Executor | None = None,
    ) -> None:
        self.classes = config.classes
        self._terrain = terrain
        self._config = config
        self._planning = planning
        self.core = Guidance(
            terrain,
            config.vehicle,
            config.planner,
            config.follower,
            self.classes,
            executor=planning,
            fence=config.safety.fence,
        )
        # The rover's own top speed: the mission's speed events name it.
        self.max_speed_mps = config.follower.max_speed_mps
        self._sink = sink
        self._event = event
        self.mode = Mode.IDLE
        self.goal: Goal | None = None

    @property
    def planner(self) -> Planner:
        return self.core.planner

    @property
    def path(self) -> Path | None:
        return self.core.path if self.mode is not Mode.WAITING_ESTIMATE and self.goal is not None else None

    def retune(self, classes: dict[int, TerrainClass], *, drive_on: bool = False) -> None:
        """Believe ``classes`` from now on (``navigator.climb_learning``, ``navigator.slide_learning``): a
        new planner on them, with the obstacles seen so far and the mission's speed limit; the goal is
        planned again on the next tick. ``drive_on`` (while ``DRIVING``): the rover follows its old path
        until the new plan comes (``Guidance.drive_on_from``), as a slide that is learned from does not hold
        it; else (held, dug in) it waits for the new plan."""
        old, config = self.core, self._config
        core = Guidance(
            self._terrain,
            config.vehicle,
            config.planner,
            config.follower,
            classes,
            executor=self._planning,
            fence=config.safety.fence,
        )
        core.take_over_from(old)
        driving_on = drive_on and self.mode is Mode.DRIVING and old.path is not None
        if driving_on:
            core.drive_on_from(old)
        old.close()
        self.core, self.classes = core, classes
        if self.goal is not None and not driving_on:
            self.mode = Mode.WAITING_ESTIMATE

    def recover(self, now: int, pose: PoseEstimate, mark: ObstacleObservation) -> None:
        """Dug in: back out, then mark the spot and plan round it (``Guidance.recover``)."""
        self.core.recover(now, (pose.x, pose.y, pose.yaw), mark)
        self.mode = Mode.RECOVERING

    def end_recovery(self, why: str) -> None:
        """A hold stopped the wheels while backing out: the back-out ends where the rover is
        (``Guidance.end_back_out``); told at the next tick."""
        self.core.end_back_out(why)
        self.mode = Mode.DRIVING

    def set_goal(self, x: float, y: float) -> None:
        self.goal = Goal(x, y)
        self.mode = Mode.WAITING_ESTIMATE

    def limit_speed(self, limit_mps: float | None) -> None:
        """The mission's speed limit from now on, or None for none (``Guidance.limit_speed``)."""
        self.core.limit_speed(limit_mps)

    def clear_goal(self) -> None:
        """No goal: the rover holds (IDLE) until the next one."""
        self.goal = None
        self.mode = Mode.IDLE

    def observe(self, observations: list[ObstacleObservation]) -> None:
        self.core.observe(observations)

    def why_stopped(self, not_ready: str) -> str:
        """Why guidance does not want to drive, in its own words: its mode, then the reason
        (``not_ready``: the start-up checks still failing, for ``WAITING_ESTIMATE``)."""
        blocker = self.core.blocker
        reason = {
            Mode.IDLE: "no goal",
            Mode.WAITING_ESTIMATE: f"start-up checks not passed ({not_ready})",
            Mode.PLANNING: "the first plan is being made",
            Mode.ARRIVED: "goal reached",
            Mode.NO_PATH: "no path to the goal",
            Mode.BLOCKED: f"moving obstacle {blocker} on the path",
            Mode.YIELDING: f"backing off from moving obstacle {blocker}",
            Mode.RECOVERING: "backing out of where it dug in",
            Mode.DRIVING: "following the path",
        }[self.mode]
        return f"guidance {self.mode.value}: {reason}"

    def tick(self, now: int, pose: PoseEstimate | None, ready: bool) -> GuidanceCommand | GuidanceOutput:
        """The command for this tick: ``STOPPED`` until a goal and the start-up checks allow driving, then
        guidance's own output (it carries the same command fields; not copied into another object)."""
        if self.mode is Mode.IDLE or pose is None:
            return STOPPED
        if self.mode is Mode.WAITING_ESTIMATE:
            if not ready or self.goal is None:
                return STOPPED
            self.core.set_goal(self.goal.x, self.goal.y)
        out = self.core.update(now, pose.x, pose.y, pose.yaw, pose.speed)
        self.mode = _MODE_OF.get(out.mode) or Mode(out.mode)  # Mode(): the enum's own error if unknown
        if self.core.recovered_waiting:  # a back-out ended: by itself, a hold or a new goal
            self._tell_recovered(now, pose)
        if out.path_changed and out.path is not None:
            self._publish_path(now, out.path)
        if out.detail:
            severity = "error" if self.mode is Mode.NO_PATH else "info"
            self._event(f"guidance.{self.mode.value.lower()}", severity, out.detail)
        return out

    def _tell_recovered(self, now: int, pose: PoseEstimate) -> None:
        """The back-out has ended: its mark, now in the planner's map, goes on the obstacle topic like any
        obstacle the planner knows (a replay leaves the stack's own marks out of its inputs), and is told."""
        recovered = self.core.take_recovered()
        if recovered is None:
            return
        why, mark = recovered
        marked = ""
        if mark is not None:
            self._sink.publish(topics.PERCEPTION_OBSTACLES, now, obstacles_record(now, [mark]))
            marked = (
                f"; marked {mark.obstacle_id} at ({mark.x:.2f}, {mark.y:.2f}), radius {mark.radius_m:.2f} m, "
                "where it dug in, as an obstacle"
            )
        outcome = "no path to the goal" if self.mode is Mode.NO_PATH else "planning the goal again"
        self._event(
            "recovery.replanned", "warning", f"{why}{marked}; {outcome} from ({pose.x:.2f}, {pose.y:.2f})"
        )

    def _publish_path(self, now: int, path: Path) -> None:
        self._sink.publish(
            topics.NAVIGATOR_PATH,
            now,
            {
                "timestamp": topics.stamp(now),
                "frame_id": topics.ENU_FRAME,
                "poses": [topics.planar_pose(float(px), float(py), 0.0) for px, py in path.points],
                "cost": path.cost,
                "length_m": path.length_m,
            },
        )
