"""Recovery when dug in: back out the way it came, mark the spot, plan round it (Nav2's BackUp, then a
replan on a costmap that marks what stopped it).

When the ``no_progress`` failsafe holds a rover guidance was driving and learning its ground's traction
(``navigator.climb_learning``) does not explain the hold (a rock under the nose, a mud hole, a slope the map
lacks, a class learned twice already), the stack recovers (``navigator.onboard_recovery`` decides when):

* guidance's mode is ``RECOVERING``: it reverses straight along its heading at ``[planner] yield_speed_mps``,
  no yaw rate, while the footprint ``YIELD_LOOK_M`` behind stays clear of the believed map's obstacles and
  edge, its centre inside the geofence (``navigator.yielding.way_blocked``, the back-off's own test), and
  the moving obstacles' predicted tracks stay clear of it (within ``inflation_m`` over ``moving_horizon_s``:
  a cart coming up behind the rover), until it is ``recovery_back_m`` from where it began (by the estimated
  pose), after ``recovery_back_m / speed + BACK_OUT_SPARE_S``, or with no clear way further back; a hold of
  the supervisor's (an e-stop, ``stuck``, ``gps_lost`` ...) or a new goal ends it where the rover stands;
* then the spot it dug in on (``dig_in_mark``) goes into the planner's map as a static obstacle for the rest
  of the run, and the goal is planned again from where it stopped.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from navigator.fence_shape import Polygon
from navigator.footprint import Footprint, disc_gap_m
from navigator.perception import ObstacleObservation
from navigator.terrain import TerrainMap, disc_mask
from navigator.vehicle import VehicleParams
from navigator.yielding import YIELD_LOOK_M, moved_along, track_gap, way_blocked

RECOVERY_BACK_M = 1.5  # default [planner] recovery_back_m
RECOVERY_ATTEMPTS = 2  # default [planner] recovery_attempts, per goal or resume
# The back-out's time bound past what its distance takes at its speed: the reverse command ramps up, and a
# rover still half dug in moves slower than commanded; a rover that does not move at all stops here.
BACK_OUT_SPARE_S = 3.0
# Marks are obstacles of the rover's own making: ids "dug-in-1", "dug-in-2", ...
MARK_PREFIX = "dug-in-"


def dig_in_mark(
    t_ns: int, pose: tuple[float, float, float], params: VehicleParams, number: int
) -> ObstacleObservation:
    """The spot a rover held at ``pose`` (x, y, yaw) dug in on, as a static obstacle: a disc around its front
    axle, as wide as the rover. What held it (a rock under the nose, the hole its front wheels sank in,
    the foot of a slope) lies under the front axle, across its whole width: a disc of half the footprint's
    width covers both front wheels' tracks, and the planner's own clearance (footprint and inflation) then
    keeps the whole rover off it. A wider disc would close gaps the rover can drive, a smaller one lets
    the planner send it over the same spot with one wheel."""
    x, y, yaw = pose
    half_base = 0.5 * params.wheelbase_m
    return ObstacleObservation(
        t_ns,
        f"{MARK_PREFIX}{number}",
        x + half_base * math.cos(yaw),
        y + half_base * math.sin(yaw),
        0.5 * params.footprint_width_m,
    )


def mark_covers(mark: ObstacleObservation, xy: tuple[float, float], clearance_m: float) -> bool:
    """Whether ``xy`` lies within ``clearance_m`` (the planner's: footprint radius and inflation) of the
    mark's disc: a goal there could no longer be reached once the mark is in the map."""
    return math.hypot(xy[0] - mark.x, xy[1] - mark.y) <= mark.radius_m + clearance_m


def mark_under(
    mark: ObstacleObservation, pose: tuple[float, float, float], footprint: Footprint, terrain: TerrainMap
) -> bool:
    """Whether the mark would lie under the rover at ``pose``: its disc overlaps the footprint, or its cells
    in ``terrain`` (at least the one holding its centre) hold the rover's centre. The planner could not
    start from there: a start inside an obstacle cell has no escape."""
    if disc_gap_m(pose, footprint, (mark.x, mark.y), mark.radius_m) < 0.0:
        return True
    x, y, _yaw = pose
    return terrain.contains(x, y) and bool(
        disc_mask(terrain, mark.x, mark.y, mark.radius_m)[terrain.cell_of(x, y)]
    )


@dataclass(frozen=True)
class BackOutLimits:
    """How a back-out moves and where it stops: ``[planner] yield_speed_mps`` and ``recovery_back_m``; and
    how near a moving obstacle's predicted track may come to the footprint behind it (``inflation_m``, over
    ``moving_horizon_s``), as for the path ahead."""

    speed_mps: float
    back_m: float = RECOVERY_BACK_M
    inflation_m: float = 0.1
    horizon_s: float = 3.0

    @property
    def max_s(self) -> float:
        return self.back_m / self.speed_mps + BACK_OUT_SPARE_S if self.speed_mps > 0.0 else 0.0


@dataclass(frozen=True)
class BackOutStep:
    """``speed_mps`` (< 0 reversing, 0 not) this tick; ``done``: the back-out is over, with ``why``."""

    speed_mps: float
    done: bool
    why: str = ""


class BackOut:
    """One back-out, begun at ``start`` (t_ns, x, y): straight back while the way is clear, bounded; then
    ``mark`` (the spot it dug in on) is for the planner's map. ``pose``: where the rover was last seen."""

    def __init__(
        self,
        footprint: Footprint,
        limits: BackOutLimits,
        start: tuple[int, float, float, float],
        mark: ObstacleObservation,
        fence: Polygon = (),
    ) -> None:
        self._footprint = footprint
        self._limits = limits
        t_ns, x, y, yaw = start
        self._start = (t_ns, x, y)
        self.pose = (x, y, yaw)
        self.mark = mark
        self._fence = fence

    def moved_m(self, pose: tuple[float, float, float]) -> float:
        _t, x0, y0 = self._start
        return math.hypot(pose[0] - x0, pose[1] - y0)

    def step(
        self,
        t_ns: int,
        pose: tuple[float, float, float],
        terrain: TerrainMap,
        moving: Mapping[str, ObstacleObservation],
    ) -> BackOutStep:
        """The command at ``pose``: reverse, or done (and why) once a bound is reached or the way behind is
        not clear of ``terrain`` or of the ``moving`` obstacles' predicted tracks."""
        limits = self._limits
        self.pose = pose
        moved_m = self.moved_m(pose)
        if moved_m >= limits.back_m:
            return BackOutStep(0.0, True, f"backed out {moved_m:.1f} m")
        elapsed_s = (t_ns - self._start[0]) * 1e-9
        if elapsed_s >= limits.max_s:
            return BackOutStep(0.0, True, f"backed out {moved_m:.1f} m in {elapsed_s:.1f} s, the limit")
        blocked = way_blocked(terrain, pose, self._footprint, -1.0, self._fence)
        if blocked:
            return BackOutStep(0.0, True, f"backed out {moved_m:.1f} m: {blocked} behind")
        if moving:
            behind = moved_along(pose, -YIELD_LOOK_M)
            gap = track_gap(moving, t_ns, behind, self._footprint, limits.horizon_s, limits.inflation_m)
            if gap.reach_s != math.inf:
                return BackOutStep(
                    0.0,
                    True,
                    f"backed out {moved_m:.1f} m: moving obstacle {gap.obstacle_id} predicted within "
                    f"{YIELD_LOOK_M:g} m behind in {gap.reach_s:.1f} s",
                )
        return BackOutStep(-limits.speed_mps, False)
