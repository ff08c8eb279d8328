"""Pure pursuit path following for a skid-steer rover: speed and yaw-rate commands toward a lookahead point.

Geometry (Coulter, "Implementation of the Pure Pursuit Path Tracking Algorithm", CMU-RI-TR-92-01): the arc
through the rover tangent to its heading and through a point ``L`` ahead at bearing ``alpha`` off the
heading has curvature ``kappa = 2 sin(alpha) / L``.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from logs.settings import Table
from navigator.errors import ParameterError
from navigator.projection_kernel import nearest_segment

REASON_MAX_SPEED = "max_speed"
REASON_CURVATURE = "curvature"
REASON_GOAL_APPROACH = "goal_approach"
REASON_TURN_IN_PLACE = "turn_in_place"
CONTROLLERS = ("pure_pursuit", "stanley")


@dataclass(frozen=True)
class FollowerConfig:
    """Tuning of the pure-pursuit follower (SI units)."""

    lookahead_m: float = 1.2
    lookahead_gain_s: float = 0.5  # lookahead grows with speed: L = lookahead_m + gain * |speed|
    max_speed_mps: float = 1.0
    max_yaw_rate_rps: float = 1.2
    max_lateral_accel_mps2: float = 1.0
    goal_tolerance_m: float = 0.5
    # Inside the tolerance the rover keeps creeping at the goal itself and stops here, or where it passes
    # the goal: stopping at the tolerance's edge put the true stop at the edge plus the estimate's error.
    goal_settle_m: float = 0.15
    slowdown_radius_m: float = 2.0
    turn_in_place_rad: float = math.radians(60.0)  # target further off the heading: stop and turn
    min_speed_mps: float = 0.1  # creep speed near the goal, so the approach slowdown still arrives
    stanley_gain: float = 1.5  # Stanley: cross-track gain k in atan(k e / (v + softening))
    stanley_softening_mps: float = 0.3  # keeps the Stanley correction finite at low speed
    heading_time_constant_s: float = 0.5  # Stanley: yaw rate = heading correction / this
    min_tip_margin_rad: float = math.radians(12.0)  # guidance slows so the tip-over margin stays above
    controller: str = "pure_pursuit"  # or "stanley"

    def __post_init__(self) -> None:
        if self.controller not in CONTROLLERS:
            raise ParameterError(
                f"follower controller must be one of {', '.join(CONTROLLERS)}, got {self.controller!r}"
            )
        for field in fields(self):
            if field.name == "controller":
                continue
            value = getattr(self, field.name)
            lower_ok = value >= 0.0 if field.name in ("lookahead_gain_s", "min_speed_mps") else value > 0.0
            if not isinstance(value, int | float) or not math.isfinite(value) or not lower_ok:
                raise ParameterError(
                    f"follower setting {field.name} must be a finite number > 0, got {value!r}"
                )
        if self.turn_in_place_rad > math.pi:
            raise ParameterError(f"follower turn_in_place_rad must be <= pi, got {self.turn_in_place_rad}")
        if self.min_speed_mps > self.max_speed_mps:
            raise ParameterError("follower min_speed_mps must not exceed max_speed_mps")
        if self.goal_settle_m > self.goal_tolerance_m:
            raise ParameterError("follower goal_settle_m must not exceed goal_tolerance_m")

    @classmethod
    def from_table(cls, table: Table) -> FollowerConfig:
        """Read a ``[follower]`` table; every key optional, unknown keys are errors (ConfigError)."""
        defaults = cls()
        values: dict[str, float] = {}
        controller = table.text("controller", defaults.controller, choices=CONTROLLERS)
        for field in fields(cls):
            if field.name == "controller":
                continue
            upper = math.pi if field.name == "turn_in_place_rad" else None
            value = table.number(field.name, getattr(defaults, field.name), lo=0.0, hi=upper)
            if value == 0.0 and field.name not in ("lookahead_gain_s", "min_speed_mps"):
                raise table.error(field.name, "must be > 0")
            values[field.name] = value
        if values["min_speed_mps"] > values["max_speed_mps"]:
            raise table.error("min_speed_mps", f"must not exceed max_speed_mps ({values['max_speed_mps']})")
        if values["goal_settle_m"] > values["goal_tolerance_m"]:
            raise table.error(
                "goal_settle_m", f"must not exceed goal_tolerance_m ({values['goal_tolerance_m']})"
            )
        table.finish()
        return cls(controller=controller, **values)


# A NamedTuple, immutable like a frozen dataclass but cheaper to build (once per control tick: the
# dataclass's __init__, an object.__setattr__ per field, was a measurable share of the tick).
class FollowCommand(NamedTuple):
    speed_mps: float
    yaw_rate_rps: float
    cross_track_error_m: float  # signed distance to the path, positive when the rover is left of it
    speed_limit_mps: float
    speed_limit_reason: str  # "max_speed", "curvature", "goal_approach" or "turn_in_place"
    arrived: bool
    curvature_1pm: float = 0.0  # the commanded path curvature (1/m, positive turning left)


def wrap_angle(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


# Inside the tolerance, the goal counts as passed once the rover is this much further from it than at
# its closest: more than the estimate's tick-to-tick jitter, less than a creep speed's worth of a second.
GOAL_PASSED_MARGIN_M = 0.05
# Inside the tolerance, a rover slower than this is not getting any closer (stuck in mud, a seized wheel,
# held by a failsafe): it has arrived where it is. A creeping rover moves at min_speed_mps (0.1 m/s).
GOAL_STALLED_MPS = 0.03


class PurePursuit:
    """Stateful follower: remembers how far along the current path the rover has got (never backwards).

    Passing a different path to ``command`` starts over at its beginning.

    Arrival: within ``goal_tolerance_m`` of the path's end (and near the end of the path) the rover keeps
    driving at the goal and arrives once it is within ``goal_settle_m``, has passed the goal (the distance
    grows again), would have to turn away to reach it, or is not moving (``GOAL_STALLED_MPS``); the
    tolerance is the radius in which it may stop, not the place it aims for.
    """

    def __init__(self, config: FollowerConfig) -> None:
        self._config = config
        self._path: np.ndarray | None = None
        # The caller's array the current path was adopted from, when it is read-only and owns its data
        # (a planner's ``Path.points``): handed in again it cannot have changed, so it is not checked and
        # compared again on every tick (None: every path handed in is checked).
        self._source: np.ndarray | None = None
        # The path's vertices and cumulative length at each vertex as Python floats: the per-tick look-ups
        # below are scalar, and numpy's per-call overhead on single elements was most of their cost.
        self._xy: list[list[float]] = []
        self._arc: list[float] = [0.0]
        self._segment = 0
        self._progress_m = 0.0
        self._closest_to_goal_m = math.inf

    @property
    def config(self) -> FollowerConfig:
        return self._config

    def reset(self) -> None:
        self._path = None
        self._source = None
        self._segment = 0
        self._progress_m = 0.0
        self._closest_to_goal_m = math.inf

    def command(self, x: float, y: float, yaw: float, speed: float, path: np.ndarray) -> FollowCommand:
        """Command for a rover at (x, y) heading ``yaw`` (ENU, rad) moving at ``speed`` along ``path``.

        ``path``: ``(n, 2)`` ENU metres, n >= 1. ParameterError for a malformed path or non-finite pose.
        """
        cfg = self._config
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(yaw) and math.isfinite(speed)):
            raise ParameterError(f"rover pose must be finite, got x={x}, y={y}, yaw={yaw}, speed={speed}")
        # The same path as on the last tick (the common case) without the call into _adopt.
        points = self._path if path is self._source and self._path is not None else self._adopt(path)
        lookahead = cfg.lookahead_m + cfg.lookahead_gain_s * abs(speed)

        projection, cross_track = self._project(points, x, y, lookahead)
        total = self._arc[-1]
        goal_x, goal_y = self._xy[-1]
        distance_to_goal = math.hypot(goal_x - x, goal_y - y)
        remaining = max(total - projection, 0.0)
        near_end = remaining <= max(lookahead, cfg.goal_tolerance_m)
        within = distance_to_goal <= cfg.goal_tolerance_m and near_end
        passed = distance_to_goal > self._closest_to_goal_m + GOAL_PASSED_MARGIN_M
        if within:
            self._closest_to_goal_m = min(self._closest_to_goal_m, distance_to_goal)
        stalled = abs(speed) < GOAL_STALLED_MPS
        if within and (distance_to_goal <= cfg.goal_settle_m or passed or stalled):
            return self._arrived(cross_track)

        heading_error, curvature = self._steer(points, x, y, yaw, speed, projection, cross_track, lookahead)
        if within and abs(heading_error) > cfg.turn_in_place_rad:
            return self._arrived(cross_track)  # the goal is beside or behind: turning back gains little
        if abs(heading_error) > cfg.turn_in_place_rad:
            yaw_rate = math.copysign(cfg.max_yaw_rate_rps, heading_error)
            return FollowCommand(0.0, yaw_rate, cross_track, 0.0, REASON_TURN_IN_PLACE, False)

        # The first (in this order) of the smallest limits names the reason: top speed, curvature, goal
        # approach. Compared as they are worked out: only a strictly smaller limit replaces the one so far.
        limit, reason = cfg.max_speed_mps, REASON_MAX_SPEED
        abs_curvature = abs(curvature)
        if abs_curvature > 1e-9:
            turn_limit = min(
                math.sqrt(cfg.max_lateral_accel_mps2 / abs_curvature), cfg.max_yaw_rate_rps / abs_curvature
            )
            if turn_limit < limit:
                limit, reason = turn_limit, REASON_CURVATURE
        approach = max(distance_to_goal, remaining)
        approach_limit = max(cfg.min_speed_mps, cfg.max_speed_mps * approach / cfg.slowdown_radius_m)
        if approach_limit < limit:
            limit, reason = approach_limit, REASON_GOAL_APPROACH
        return FollowCommand(limit, limit * curvature, cross_track, limit, reason, False, curvature)

    def _arrived(self, cross_track: float) -> FollowCommand:
        return FollowCommand(0.0, 0.0, cross_track, 0.0, REASON_GOAL_APPROACH, True)

    def _steer(
        self,
        points: np.ndarray,
        x: float,
        y: float,
        yaw: float,
        speed: float,
        projection: float,
        cross_track: float,
        lookahead: float,
    ) -> tuple[float, float]:
        """(heading error rad, curvature 1/m): the arc through the lookahead point (pure pursuit)."""
        target = self._point_at(projection + lookahead)
        bearing_error = wrap_angle(math.atan2(target[1] - y, target[0] - x) - yaw)
        chord = max(math.hypot(target[0] - x, target[1] - y), 1e-6)
        return bearing_error, 2.0 * math.sin(bearing_error) / chord

    # --- path bookkeeping -------------------------------------------------------------------------
    def _adopt(self, path: np.ndarray) -> np.ndarray:
        """Check and take in a path that is not the one adopted last (``command`` keeps that one itself)."""
        points = np.asarray(path, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 2 or points.shape[0] < 1:
            raise ParameterError(
                f"path must be an (n, 2) array of ENU points with n >= 1, got {points.shape}"
            )
        if not np.all(np.isfinite(points)):
            raise ParameterError("path holds non-finite points")
        if self._path is None or self._path.shape != points.shape or not np.array_equal(self._path, points):
            self._path = points.copy()
            lengths = np.hypot(*np.diff(points, axis=0).T) if len(points) > 1 else np.zeros(0)
            self._arc = np.concatenate([[0.0], np.cumsum(lengths)]).tolist()
            self._xy = points.tolist()
            self._segment = 0
            self._progress_m = 0.0
            self._closest_to_goal_m = math.inf
        unchangeable = isinstance(path, np.ndarray) and not path.flags.writeable and path.base is None
        self._source = path if unchangeable else None
        return self._path

    def _project(self, points: np.ndarray, x: float, y: float, lookahead: float) -> tuple[float, float]:
        """Arc length of the rover's projection on the path and its signed cross-track error.

        Only segments from the current one up to a window ahead are searched, so a path that doubles back
        near itself cannot make the projection jump; the chosen segment index never decreases.
        """
        if len(points) == 1:
            return 0.0, 0.0
        window_end = self._progress_m + 2.0 * lookahead + 1.0
        # bisect_right on the (non-decreasing) arc list: the index np.searchsorted(side="right") gives.
        last = bisect.bisect_right(self._arc, window_end)
        first = self._segment
        last = min(max(last, first + 1), len(points) - 1)
        segment, t, nearest_x, nearest_y, dx, dy, length_sq = nearest_segment(points, first, last, x, y)
        self._segment = segment
        length = math.sqrt(length_sq)
        projection = self._arc[segment] + t * length
        self._progress_m = max(self._progress_m, projection)
        cross_track = (dx / length) * (y - nearest_y) - (dy / length) * (x - nearest_x)
        return projection, cross_track

    def _point_at(self, arc_m: float) -> tuple[float, float]:
        """The (x, y) of the path point ``arc_m`` along the path (clamped to its ends)."""
        arc, xy = self._arc, self._xy
        if len(xy) == 1 or arc_m >= arc[-1]:
            return xy[-1][0], xy[-1][1]
        index = bisect.bisect_right(arc, arc_m) - 1
        index = min(max(index, 0), len(xy) - 2)
        span = arc[index + 1] - arc[index]
        fraction = 0.0 if span <= 0.0 else (arc_m - arc[index]) / span
        # Per coordinate the arithmetic numpy did on the two rows: the same floats.
        (x0, y0), (x1, y1) = xy[index], xy[index + 1]
        return x0 + fraction * (x1 - x0), y0 + fraction * (y1 - y0)
