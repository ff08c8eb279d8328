"""Guidance: planning, replanning and path following in one object, the navigator's drive loop brain.

``Guidance`` owns a ``Planner`` (the believed map) and a follower (pure pursuit or Stanley). Each control
tick calls ``update`` with the estimated pose and gets speed, yaw rate, a mode and the reason for the
current speed limit. Planning (obstacles into the map, then a plan) is a job on an injected executor
(``navigator.plan_worker``): a worker thread in real time, so a long plan never delays a tick (the rover
follows its last path meanwhile, or holds in ``PLANNING`` with none); inline in lockstep HIL and tests,
so the plan is there within the same tick. Obstacles seen on the way come in through ``observe``:

* a *static* obstacle not seen before (and within ``sensing_range_m`` of the rover) is added to the map.
  The plan is then *repaired*: costs only ever rise when obstacles are added, so a remaining path that
  touches no cell whose cost changed is still optimal and is kept (checked in O(path length)); otherwise
  a new plan is made from the current pose, with the goal's cost-to-go field (built on the first plan to
  that goal, still a consistent lower bound since costs only rose) as the A* heuristic, so it expands
  little more than the detour (``navigator.replanning``) and costs the same as a fresh plan;
* a *moving* obstacle is tracked (latest observation per id); if its constant-velocity prediction comes
  within clearance of the path ahead within ``moving_horizon_s``, the rover stops (mode ``BLOCKED``) until
  the way has stayed clear for ``moving_clear_s``. While stopped so, if an obstacle's predicted track
  reaches the rover's own footprint (it stands in the obstacle's lane), it backs off, bounded (mode
  ``YIELDING``, ``navigator.yielding``), then holds as ``BLOCKED``.

Dug in (the stack says so: ``recover``), it backs out straight, bounded (mode ``RECOVERING``,
``navigator.recovery``), then marks the spot it dug in on as a static obstacle and plans the goal again
from where it stopped.

Speed limits on top of the follower's (curvature, goal approach): the mission's (``limit_speed``: a
MAV_CMD_DO_CHANGE_SPEED item, ``navigator.onboard_mission``), the slope under the rover, the terrain
class, and the predicted tip-over margin: on a side slope of roll ``r`` the lateral acceleration ``v^2 k``
of a turn may use only ``g tan(tip_roll - min_tip_margin - |r|)``. Each only ever lowers the target speed.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from concurrent.futures import Executor, Future
from typing import NamedTuple

import numpy as np

from navigator.config import PlannerConfig
from navigator.errors import ParameterError
from navigator.fence_shape import Polygon
from navigator.follower import FollowCommand, FollowerConfig, PurePursuit
from navigator.footprint import Footprint
from navigator.perception import ObstacleObservation
from navigator.plan_worker import InlineExecutor, PlanOutcome, PlanRequest, in_range, run_plan_request
from navigator.planner import Path, Planner
from navigator.recovery import BackOut, BackOutLimits, mark_under
from navigator.stanley import Stanley
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TERRAIN_CLASSES, TerrainClass
from navigator.vehicle import VehicleParams, turn_acceleration_room
from navigator.yielding import BackOff, BackOffStep, YieldLimits, predicted_track

_log = logging.getLogger(__name__)

IDLE = "IDLE"
DRIVING = "DRIVING"
ARRIVED = "ARRIVED"
NO_PATH = "NO_PATH"
BLOCKED = "BLOCKED"
PLANNING = "PLANNING"  # a goal, no path yet: the first plan is being made (wheels held)
YIELDING = "YIELDING"  # backing off out of a moving obstacle's predicted track (navigator.yielding)
RECOVERING = "RECOVERING"  # dug in: backing out the way it came, then marking the spot (navigator.recovery)

REASON_MISSION_SPEED = "mission_speed"
REASON_SLOPE = "slope"
REASON_TERRAIN = "terrain_class"
REASON_TIP_MARGIN = "tip_margin"
REASON_MOVING_OBSTACLE = "moving_obstacle"
REASON_STOPPED = "stopped"
REASON_RECOVERY = "recovery"

# A rover further than this off its path replans from where it is (it was pushed, slid or mis-estimated).
REPLAN_CROSS_TRACK_M = 2.0


# A NamedTuple, immutable like a frozen dataclass but cheaper to build (once per control tick: the
# dataclass's __init__, an object.__setattr__ per field, was a measurable share of the tick).
class GuidanceOutput(NamedTuple):
    speed_mps: float
    yaw_rate_rps: float
    mode: str
    cross_track_error_m: float
    speed_limit_mps: float
    speed_limit_reason: str
    path: Path | None
    path_changed: bool  # a new path was made on this tick (publish it)
    arrived: bool
    detail: str  # what happened on this tick, for logs and events ("" when nothing new)


class Guidance:
    """Plans to a goal, repairs the plan as obstacles appear, and follows it within safe speed limits."""

    def __init__(
        self,
        terrain: TerrainMap,
        params: VehicleParams,
        planner_config: PlannerConfig,
        follower_config: FollowerConfig,
        classes: dict[int, TerrainClass] = TERRAIN_CLASSES,
        *,
        executor: Executor | None = None,
        fence: Polygon = (),
    ) -> None:
        """``executor`` runs the planning jobs (default: inline, in ``update``; see the module doc);
        ``fence``, the ``[safety] fence`` (empty: none), which no back-off nor back-out leaves."""
        self._params = params
        self._fence = fence
        self._executor: Executor = executor if executor is not None else InlineExecutor()
        self._job: Future[PlanOutcome] | None = None
        self._generation = 0  # counts goals: an outcome planned for an older goal is stale
        self._classes = classes
        self._config = planner_config
        self._follower_config = follower_config
        self.planner = Planner.from_config(
            terrain,
            params,
            planner_config,
            classes=classes,
            # Every replan to the same goal reuses its cost-to-go field: a repair after new obstacles
            # or from a new pose expands little more than the new path (navigator.replanning).
            reuse_goal_field=True,
        )
        self._follower: PurePursuit = (
            Stanley(follower_config)
            if follower_config.controller == "stanley"
            else PurePursuit(follower_config)
        )
        self._clearance_m = params.footprint_radius_m + planner_config.inflation_m
        # For the speed limits of every tick, worked out once: the slope limit's divisor, each terrain
        # class's limit (the classes are fixed for the guidance's life) and the tilt a turn may bring the
        # specific force to (the tip angle less the margin kept).
        self._tan_tip_roll = math.tan(params.tip_roll_rad)
        self._terrain_limit_mps = {
            terrain_class: follower_config.max_speed_mps / math.sqrt(max(spec.cost_factor, 1.0))
            for terrain_class, spec in classes.items()
        }
        self._turn_tilt_limit_rad = params.tip_roll_rad - follower_config.min_tip_margin_rad
        # The mission's speed limit (``limit_speed``); infinity when there is none: one comparison a tick.
        self._mission_speed_mps = math.inf
        self._goal: tuple[float, float] | None = None
        self._path: Path | None = None
        self._mode = IDLE
        self._needs_plan = False
        # Static obstacles in the map, by id: the sighting each went in with (to rebuild the map when one
        # moves on), and the ids that were in it and have since been seen moving, to take off at the next
        # planning job.
        self._in_map: dict[str, ObstacleObservation] = {}
        self._moved_off: set[str] = set()
        # Static obstacles seen but not yet in the map, by id: the newest sighting of each (perception
        # reports an obstacle every cycle while it is in view, and the rover may take minutes to get near).
        self._pending: dict[str, ObstacleObservation] = {}
        self._moving: dict[str, ObstacleObservation] = {}
        # The moving obstacle holding the rover in BLOCKED: reported when it starts or stops blocking, not
        # on every tick in between (a 10 s wait was 500 identical events).
        self._blocker: str | None = None
        # The speed it was stopped from: the way counts as clear only for the corridor that speed needs.
        # Judged at standstill the corridor shrinks to its 3 m minimum, the obstacle falls outside it, the
        # rover starts, the corridor grows and it stops again: BLOCKED flickered every few ticks.
        self._blocked_at_speed = 0.0
        # When the way was first judged clear in this BLOCKED wait (None: not clear, or not blocked). The
        # rover leaves BLOCKED only after moving_clear_s of it: a cart turning at the end of its track was
        # once clear for 0.34 s, the rover started, and it was BLOCKED again for 0.24 s.
        self._clear_since_ns: int | None = None
        self._clear_hold_ns = round(planner_config.moving_clear_s * 1e9)
        self._moving_forget_ns = round(planner_config.moving_forget_s * 1e9)
        # Stopped in a moving obstacle's way is not safe: the back-off of the current wait.
        self._back_off = BackOff(
            Footprint.of(params),
            planner_config.inflation_m,
            planner_config.moving_horizon_s,
            YieldLimits(
                planner_config.yield_speed_mps,
                planner_config.yield_margin_m,
                planner_config.yield_max_m,
                planner_config.yield_max_s,
            ),
            fence,
        )
        # Backing out when dug in (navigator.recovery): the back-out under way and the mark it leaves, the
        # marks waiting for the next planning job (they go in whatever the sensing range: ground the rover
        # stood on), and what the last back-out did, for the stack to tell (``take_recovered``).
        self._back_out_limits = BackOutLimits(
            planner_config.yield_speed_mps,
            planner_config.recovery_back_m,
            planner_config.inflation_m,
            planner_config.moving_horizon_s,
        )
        self._back_out: BackOut | None = None
        self._marks_waiting: list[ObstacleObservation] = []
        self._recovered: tuple[str, ObstacleObservation | None] | None = None
        self._last_xy: tuple[float, float] | None = None
        self.replans = 0
        self.repairs_kept = 0

    @property
    def mode(self) -> str:
        return self._mode

    @property
    def path(self) -> Path | None:
        return self._path

    @property
    def goal(self) -> tuple[float, float] | None:
        return self._goal

    @property
    def blocker(self) -> str | None:
        """Id of the moving obstacle predicted on the path while the mode is ``BLOCKED`` or ``YIELDING``,
        else None."""
        return self._blocker

    @property
    def mission_speed_mps(self) -> float | None:
        """The mission's speed limit in force (m/s), or None."""
        limit = self._mission_speed_mps
        return None if limit == math.inf else limit

    def take_over_from(self, old: Guidance) -> None:
        """What ``old`` knew, as it knew it (a guidance on other beliefs taking over,
        ``RouteGuidance.retune``): the static obstacles in its map (into this planner's map at once, however
        far), the ones waiting to go in, the moving ones, and its mission speed limit. Before the first
        planning job: the planner is this thread's until then."""
        self._in_map, self._pending = dict(old._in_map), dict(old._pending)
        self._marks_waiting = list(old._marks_waiting)
        self._moving, self._moved_off = dict(old._moving), set(old._moved_off)
        added = old.planner.terrain.obstacles & ~self.planner.terrain.obstacles
        if added.any():
            self.planner.update_obstacles(added)
        self.limit_speed(old.mission_speed_mps)

    def drive_on_from(self, old: Guidance) -> None:
        """Take ``old``'s goal and path too, and plan that goal again at once on this guidance's beliefs,
        following the old path until the new plan comes (``RouteGuidance.retune`` with ``drive_on``: a rover
        that learned from a slide is moving; stopping for the plan would leave it sliding in place). After
        ``take_over_from``; only while ``old`` drives its path."""
        self._goal, self._path = old._goal, old._path
        self._generation = old._generation + 1  # a plan ``old`` had in flight is for the old beliefs
        self._needs_plan = self._goal is not None
        self._mode = old._mode

    def limit_speed(self, limit_mps: float | None) -> None:
        """The mission's speed limit from now on (m/s, > 0 and finite), or None for none. It caps the
        target speed while following a path, whatever the goal, below the follower's and never above
        any other limit; not a back-off (``YIELDING``), whose speed is a safety setting of its own.
        ``ParameterError`` (the limit in force kept) for a value that is no speed."""
        if limit_mps is None:
            self._mission_speed_mps = math.inf
            return
        if not (isinstance(limit_mps, int | float) and math.isfinite(limit_mps) and limit_mps > 0.0):
            raise ParameterError(f"a speed limit must be a finite number > 0 m/s, got {limit_mps!r}")
        self._mission_speed_mps = float(limit_mps)

    def set_goal(self, x: float, y: float) -> None:
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ParameterError(f"goal must be finite, got ({x}, {y})")
        self._goal = (float(x), float(y))
        self._generation += 1
        self._path = None
        self._needs_plan = True
        self._mode = DRIVING
        self._blocker = None
        self._clear_since_ns = None
        self._back_off.reset()
        if self._back_out is not None:  # the operator chose where to go: the back-out ends here
            self._end_back_out(self._back_out, self._back_out.pose, "a new goal ended the back-out")
        self._follower.reset()

    def recover(self, t_ns: int, pose: tuple[float, float, float], mark: ObstacleObservation) -> None:
        """Dug in at ``pose`` (x, y, yaw): back out from here (mode ``RECOVERING``), then put ``mark`` into
        the map and plan the goal again from where the back-out stopped (``navigator.recovery``)."""
        self._back_out = BackOut(
            Footprint.of(self._params), self._back_out_limits, (t_ns, *pose), mark, self._fence
        )
        self._mode = RECOVERING
        self._blocker = None

    def end_back_out(self, why: str) -> None:
        """End the back-out under way where the rover was last seen (the stack's word: a hold of the
        supervisor's stops the wheels), as if it had ended by itself there; nothing if none is."""
        if self._back_out is not None:
            self._end_back_out(self._back_out, self._back_out.pose, why)

    @property
    def recovered_waiting(self) -> bool:
        """Whether a back-out has ended whose outcome ``take_recovered`` has not yet given."""
        return self._recovered is not None

    def take_recovered(self) -> tuple[str, ObstacleObservation | None] | None:
        """What the back-out that has just ended did and the mark it left (None: none, it lay under the
        rover), once; else None."""
        recovered, self._recovered = self._recovered, None
        return recovered

    @property
    def planning(self) -> bool:
        """Whether a planning job is in flight."""
        return self._job is not None

    def observe(self, observations: Iterable[ObstacleObservation]) -> None:
        """Take in obstacle observations (any number, any order); acted on at the next ``update``."""
        for obs in observations:
            if (
                # map(): the same tests as a generator expression, without its frame per observation.
                not all(map(math.isfinite, (obs.x, obs.y, obs.radius_m, obs.vx, obs.vy))) or obs.radius_m < 0
            ):
                _log.warning(
                    "rejected obstacle observation %r: non-finite or negative values", obs.obstacle_id
                )
                continue
            if obs.moving:
                self._moving[obs.obstacle_id] = obs
                # Seen standing before (a cart waiting to start): not part of the map any more.
                self._pending.pop(obs.obstacle_id, None)
                if self._in_map.pop(obs.obstacle_id, None) is not None:
                    self._moved_off.add(obs.obstacle_id)
            elif obs.obstacle_id not in self._in_map:
                self._moving.pop(obs.obstacle_id, None)  # it stopped: from now on part of the map
                self._pending[obs.obstacle_id] = obs

    def update(self, t_ns: int, x: float, y: float, yaw: float, speed: float) -> GuidanceOutput:
        """One tick: repair or make the plan as needed, then the command for the pose (ENU m, rad, m/s)."""
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(yaw) and math.isfinite(speed)):
            raise ParameterError(f"pose must be finite, got x={x}, y={y}, yaw={yaw}, speed={speed}")
        self._last_xy = (x, y)
        if self._back_out is not None:
            backing = self._backing_out(t_ns, x, y, yaw)
            if backing is not None:
                return backing
        details: list[str] = []
        path_changed = self._collect(details) if self._job is not None else False
        if self._job is None:
            self._submit(x, y)
            if self._job is not None:
                path_changed |= self._collect(details)  # an inline executor has finished already
        if self._goal is None:
            return self._stopped(IDLE, "", path_changed)
        if self._mode == ARRIVED:
            return self._stopped(ARRIVED, "", path_changed, arrived=True)
        if self._path is None:
            waiting = self._job is not None or self._needs_plan
            return self._stopped(PLANNING if waiting else NO_PATH, _joined(details), path_changed)
        command = self._follower.command(x, y, yaw, speed, self._path.points)
        off_path = abs(command.cross_track_error_m) > REPLAN_CROSS_TRACK_M and not command.arrived
        if off_path and self._job is None:
            # A plan from where the rover is; in real time it keeps following the old path meanwhile.
            self._submit(x, y, why=f"{command.cross_track_error_m:+.1f} m off the path", must_plan=True)
            changed = self._collect(details)
            if self._path is None:
                return self._stopped(NO_PATH, _joined(details), True)
            if changed:
                path_changed = True
                command = self._follower.command(x, y, yaw, speed, self._path.points)
        detail = _joined(details) if details else ""
        if command.arrived:
            self._mode = ARRIVED
            return self._stopped(ARRIVED, detail or "goal reached", path_changed, arrived=True)
        if self._moving and self._moving_forget_ns:
            self._forget_unseen_movers(t_ns)
        judged_speed = max(abs(speed), self._blocked_at_speed) if self._blocker is not None else abs(speed)
        blocker = self._blocking_obstacle(t_ns, x, y, judged_speed) if self._moving else None
        if blocker is not None:
            self._clear_since_ns = None
        elif self._blocker is not None and not self._clear_long_enough(t_ns):
            blocker = self._blocker  # clear, but not for long enough yet: still waiting
        if blocker is not None:
            if self._blocker is None:
                self._blocked_at_speed = abs(speed)
                self._back_off.reset()
            if blocker != self._blocker:
                detail = _joined([detail, f"moving obstacle {blocker} predicted on the path"])
            self._blocker = blocker
            step = self._back_off.step(t_ns, (x, y, yaw), self._moving, self.planner.terrain)
            return self._waiting(step, command.cross_track_error_m, path_changed, detail)
        if self._blocker is not None:
            detail = _joined([detail, f"way clear: moving obstacle {self._blocker} no longer on the path"])
            self._blocker = None
            self._clear_since_ns = None
            self._back_off.reset()
        self._mode = DRIVING
        return self._limited(command, x, y, yaw, path_changed, detail)

    # --- planning -------------------------------------------------------------------------------------
    def _submit(self, x: float, y: float, *, why: str = "", must_plan: bool = False) -> None:
        """Start a planning job if there is work: static obstacles now within range, obstacles in the map
        that have moved on, or a plan needed."""
        if not (self._pending or self._moved_off or self._needs_plan or must_plan or self._marks_waiting):
            return  # nothing asks for planning (nearly every tick): no list built, nothing filtered
        near = [o for o in self._pending.values() if in_range(o, (x, y), self._config.sensing_range_m)]
        near.extend(self._marks_waiting)
        self._marks_waiting = []
        must_plan = must_plan or (self._needs_plan and self._goal is not None and self._mode != ARRIVED)
        if not near and not must_plan and not self._moved_off:
            return
        # Obstacles not yet within sensing range wait until the rover is near.
        for obstacle in near:
            self._pending.pop(obstacle.obstacle_id, None)
        self._in_map.update((o.obstacle_id, o) for o in near)
        moved_off, self._moved_off = tuple(sorted(self._moved_off)), set()
        if must_plan:
            self._needs_plan = False
        request = PlanRequest(
            generation=self._generation,
            start_xy=(x, y),
            # Arrived: obstacles still go into the map, but nothing is planned until a new goal.
            goal=None if self._mode == ARRIVED else self._goal,
            new_obstacles=tuple(near),
            path=self._path,
            must_plan=must_plan,
            retry_no_path=self._mode == NO_PATH,
            why=why,
            moved_off=moved_off,
            static_obstacles=tuple(self._in_map.values()) if moved_off else (),
        )
        self._job = self._executor.submit(run_plan_request, self.planner, request)

    def _collect(self, details: list[str]) -> bool:
        """Take in a finished job's outcome; returns whether it brought a new path (``_path`` is None
        after a failed plan)."""
        job = self._job
        if job is None or not job.done():
            return False
        self._job = None
        outcome = job.result()
        details.extend(outcome.details)
        if outcome.repair_kept:
            self.repairs_kept += 1
        if not outcome.planned:
            return False
        if outcome.generation != self._generation:
            self._needs_plan = self._goal is not None  # planned for an older goal: plan for this one
            return False
        self._path = outcome.path
        if outcome.path is None:
            self._mode = NO_PATH
            return False
        self.replans += 1
        self._follower.reset()
        return True

    # --- backing out when dug in ----------------------------------------------------------------------
    def _backing_out(self, t_ns: int, x: float, y: float, yaw: float) -> GuidanceOutput | None:
        """The back-out's command (``RECOVERING``), or None once it has ended: then the mark waits for the
        planning job this tick starts, a plan from here to the goal (one for the old path, in flight,
        counts as stale), and the mode is ``DRIVING`` again. A mark that would overlap the rover where the
        back-out stopped (it could not back out) is left out: the planner could never start from inside it,
        for this goal or any later one."""
        back_out = self._back_out
        if back_out is None:
            return None
        step = back_out.step(t_ns, (x, y, yaw), self.planner.terrain, self._moving)
        if not step.done:
            return GuidanceOutput(
                step.speed_mps, 0.0, RECOVERING, 0.0, self._back_out_limits.speed_mps, REASON_RECOVERY,
                self._path, False, False, "",
            )  # fmt: skip
        self._end_back_out(back_out, (x, y, yaw), step.why)
        return None

    def _end_back_out(self, back_out: BackOut, pose: tuple[float, float, float], why: str) -> None:
        """The back-out has ended at ``pose``, ``why``: its mark waits for the next planning job (unless it
        lies under the rover), the goal is planned again from here, the mode is ``DRIVING``."""
        self._back_out = None
        mark = back_out.mark
        if mark_under(mark, pose, Footprint.of(self._params), self.planner.terrain):
            self._recovered = (f"{why}; not marked: the spot it dug in on lies under it", None)
        else:
            self._marks_waiting.append(mark)
            self._recovered = (why, mark)
        self._generation += 1
        self._path = None
        self._needs_plan = True
        self._mode = DRIVING
        self._follower.reset()

    # --- moving obstacles -----------------------------------------------------------------------------
    def _clear_long_enough(self, t_ns: int) -> bool:
        """Whether the way, judged clear now, has been clear for ``moving_clear_s`` of this wait."""
        if self._clear_since_ns is None:
            self._clear_since_ns = t_ns
        return t_ns - self._clear_since_ns >= self._clear_hold_ns

    def _forget_unseen_movers(self, t_ns: int) -> None:
        """Drop the moving obstacles last seen more than ``moving_forget_s`` ago: one predicted on from an
        old sighting for ever would hold the rover for a cart long gone (a lidar track's id, once
        forgotten, never comes back)."""
        oldest_ns = t_ns - self._moving_forget_ns
        stale = [key for key, obs in self._moving.items() if obs.t_ns < oldest_ns]
        for key in stale:
            del self._moving[key]

    def _blocking_obstacle(self, t_ns: int, x: float, y: float, speed: float) -> str | None:
        if not self._moving or self._path is None:
            return None
        points = self._path.points
        start = int(np.argmin(np.hypot(points[:, 0] - x, points[:, 1] - y)))
        reach = max(3.0, abs(speed) * self._config.moving_horizon_s + self._follower_config.lookahead_m)
        ahead = [np.array([x, y])]
        travelled = 0.0
        for point in points[start + 1 :]:
            travelled += float(np.hypot(*(point - ahead[-1])))
            ahead.append(point)
            if travelled > reach:
                break
        corridor = np.array(ahead)
        for obstacle_id, obs in sorted(self._moving.items()):
            track = predicted_track(obs, t_ns, self._config.moving_horizon_s)
            xs, ys = track[:, 0], track[:, 1]
            gaps = np.hypot(corridor[:, 0][:, None] - xs[None, :], corridor[:, 1][:, None] - ys[None, :])
            if float(gaps.min()) < obs.radius_m + self._clearance_m:
                return obstacle_id
        return None

    def _waiting(
        self, step: BackOffStep, cross_track_m: float, path_changed: bool, detail: str
    ) -> GuidanceOutput:
        """The command while a moving obstacle holds the rover: straight back (no yaw rate: the way it
        came) or, failing that, straight on while the back-off says so, else standing still."""
        self._mode = YIELDING if step.moving else BLOCKED
        limit = self._config.yield_speed_mps if step.moving else 0.0
        return GuidanceOutput(
            step.speed_mps, 0.0, self._mode, cross_track_m, limit, REASON_MOVING_OBSTACLE, self._path,
            path_changed, False, _joined([detail, step.detail]),
        )  # fmt: skip

    # --- speed limits ---------------------------------------------------------------------------------
    def _limited(
        self, command: FollowCommand, x: float, y: float, yaw: float, path_changed: bool, detail: str
    ) -> GuidanceOutput:
        cfg = self._follower_config
        # The first (in this order) of the smallest limits names the reason: follower, mission, slope, terrain
        # class, tip margin. Compared as they are worked out: only a strictly smaller limit replaces the one
        # so far.
        limit, reason = command.speed_limit_mps, command.speed_limit_reason
        if self._mission_speed_mps < limit:
            limit, reason = self._mission_speed_mps, REASON_MISSION_SPEED
        # Class and tilt in one look-up; None off the map.
        ground = self.planner.terrain.ground_on_map(x, y, yaw) if command.speed_mps > 0.0 else None
        if ground is not None:
            roll, pitch = ground.roll_rad, ground.pitch_rad
            abs_roll, abs_pitch = abs(roll), abs(pitch)
            tilt = abs_pitch if abs_pitch > abs_roll else abs_roll  # max(abs(roll), abs(pitch)), same pick
            slope_scale = 1.0 - math.tan(tilt) / self._tan_tip_roll
            slope_scale = slope_scale if slope_scale > 0.3 else 0.3  # max(0.3, scale), NaN too
            candidate = cfg.max_speed_mps * slope_scale
            if candidate < limit:
                limit, reason = candidate, REASON_SLOPE
            candidate = self._terrain_limit_mps[ground.terrain_class]
            if candidate < limit:
                limit, reason = candidate, REASON_TERRAIN
            curvature = abs(command.curvature_1pm)
            if curvature > 1e-9:
                # The turn's v^2 kappa may tilt the specific force to the margin, as the simulator judges it.
                lateral = turn_acceleration_room(self._turn_tilt_limit_rad, roll, pitch)
                candidate = max(math.sqrt(lateral / curvature), cfg.min_speed_mps)
                if candidate < limit:
                    limit, reason = candidate, REASON_TIP_MARGIN
        speed, yaw_rate = command.speed_mps, command.yaw_rate_rps
        if speed > limit > 0.0:
            # Scale speed and yaw rate together: the curvature the follower asked for is kept.
            yaw_rate *= limit / speed
            speed = limit
        return GuidanceOutput(
            speed, yaw_rate, DRIVING, command.cross_track_error_m, limit, reason, self._path, path_changed,
            False, detail,
        )  # fmt: skip

    def close(self) -> None:
        """Forget a job in flight (its outcome is never read); the executor belongs to the caller."""
        if self._job is not None:
            self._job.cancel()
            self._job = None

    def _stopped(
        self, mode: str, detail: str, path_changed: bool, *, arrived: bool = False
    ) -> GuidanceOutput:
        self._mode = mode
        self._blocker = None
        return GuidanceOutput(
            0.0, 0.0, mode, 0.0, 0.0, REASON_STOPPED, self._path, path_changed, arrived, detail,
        )  # fmt: skip


def _joined(details: list[str]) -> str:
    return "; ".join([d for d in details if d]) if details else ""
