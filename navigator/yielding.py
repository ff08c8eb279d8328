"""Backing off from a moving obstacle whose predicted track reaches where the rover stands.

``BLOCKED`` stops the rover for a moving obstacle predicted on the path ahead. Stopping is only safe if the
rover is out of the obstacle's way: a rover stopped with a corner of its footprint in a cart's lane was hit
by the cart (carts follow their waypoints and never avoid anything). So while stopped, guidance also asks
whether a moving obstacle's constant-velocity track over ``moving_horizon_s`` comes within ``inflation_m`` of
the rover's footprint rectangle at its CURRENT pose (``navigator.footprint.disc_gap_m``). If so the rover
moves out of the way (mode ``YIELDING``) at ``YIELD_SPEED_MPS`` with no yaw rate:

* straight back along its heading (it came along the path, so this is the path behind it) if the footprint
  ``YIELD_LOOK_M`` back is clear of the believed map's obstacles and edge and further from the tracks;
* else straight on, on the same test: a rover that had nearly crossed the lane, its rear still in it,
  backed further into it and was hit by a 1 m/s cart;
* else it holds.

It goes on that way while the footprint ``YIELD_LOOK_M`` on stays clear of the map and further from the
tracks, until the tracks clear the footprint by ``inflation_m + YIELD_MARGIN_M`` (the margin keeps it from
stopping on the edge and starting again); then it holds as ``BLOCKED`` does. The back-off is bounded: at
``YIELD_MAX_M`` from where it began, after ``YIELD_MAX_S``, or with no clear way further out, it holds
(speed 0, ``BLOCKED``) for the rest of that wait and moves no more, whatever the prediction says: reversing
blindly is worse than a bounded, reported hold. A new wait (after the way has been clear for
``moving_clear_s``) starts a new budget. Everything is judged from the guidance clock and the pose, so a
lockstep run stays deterministic.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from navigator.fence_shape import Polygon, inside_polygon
from navigator.footprint import Footprint, disc_gap_m, footprint_collides
from navigator.perception import ObstacleObservation
from navigator.terrain import TerrainMap

# Defaults of the back-off's [planner] settings (``YieldLimits``; ``PlannerConfig.yield_*``).
YIELD_SPEED_MPS = 0.5  # reverse speed: half the default max speed, yet out of a 0.8 m/s cart's lane in time
YIELD_MARGIN_M = 0.3  # the track must clear the footprint by inflation + this before the rover holds again
YIELD_MAX_M = 3.0  # at most this far back from where the back-off began ...
YIELD_MAX_S = 10.0  # ... and for at most this long (s of the guidance clock); then hold
YIELD_LOOK_M = (
    0.5  # the footprint this far on must be clear of the map's obstacles and further from the track
)
PREDICTION_STEP_S = 0.25
_SAME_M = 1e-6  # gaps closer than this are the same gap


def predicted_track(obs: ObstacleObservation, t_ns: int, horizon_s: float) -> np.ndarray:
    """Where ``obs`` is predicted at constant velocity from ``t_ns`` to ``t_ns + horizon_s`` (every
    ``PREDICTION_STEP_S``): ``(n, 2)`` ENU metres; its age since the observation is added first."""
    steps = np.arange(0.0, horizon_s + 1e-9, PREDICTION_STEP_S)
    age_s = max(0.0, (t_ns - obs.t_ns) * 1e-9)
    return np.column_stack([obs.x + obs.vx * (age_s + steps), obs.y + obs.vy * (age_s + steps)])


@dataclass(frozen=True)
class YieldLimits:
    """How a back-off moves and where it stops (``[planner] yield_speed_mps``, ``yield_margin_m``,
    ``yield_max_m``, ``yield_max_s``): a heavier or faster rover, or a yard with faster carts, sets its own.
    A speed of 0 never backs off (the rover holds, as before the back-off existed)."""

    speed_mps: float = YIELD_SPEED_MPS
    margin_m: float = YIELD_MARGIN_M
    max_m: float = YIELD_MAX_M
    max_s: float = YIELD_MAX_S


@dataclass(frozen=True)
class TrackGap:
    """How close the moving obstacles' predicted tracks come to the footprint at one pose: ``gap_m`` the
    smallest gap (< 0: overlap; ``inf``: nothing tracked), ``obstacle_id`` whose, and ``reach_s`` the
    first prediction time any track comes within the limit asked for (``inf``: none does), and
    ``centre_m`` how close the tracks come to the footprint's centre (minus each obstacle's radius)."""

    gap_m: float
    obstacle_id: str | None
    reach_s: float
    centre_m: float = math.inf

    def further_than(self, other: TrackGap) -> bool:
        """Reached later, or as late and with more room, or as late with as much room (none: the track
        crosses the footprint) and further from its centre. Time first: a pose the track overlaps has gap
        ``-radius`` however deep, so a rover backing away from an obstacle that comes at it end-on only
        gains time. The centre last: a rover straddling a lane that crosses it has gap ``-radius`` and the
        same reach backing or not, yet backing takes it towards the lane's edge (seen: it held in the
        middle of a 1 m/s cart's lane, "0.5 m further would be no further from the track", and was hit)."""
        if self.reach_s != other.reach_s:
            return self.reach_s > other.reach_s
        if abs(self.gap_m - other.gap_m) > _SAME_M:
            return self.gap_m > other.gap_m
        return self.centre_m > other.centre_m + _SAME_M


def track_gap(
    moving: Mapping[str, ObstacleObservation],
    t_ns: int,
    pose: tuple[float, float, float],
    footprint: Footprint,
    horizon_s: float,
    limit_m: float = 0.0,
) -> TrackGap:
    """The moving obstacles' predicted tracks against the footprint rectangle at ``pose`` (x, y, yaw)."""
    return _gap_to_tracks(_tracks(moving, t_ns, horizon_s), pose, footprint, limit_m)


# (obstacle id, its predicted track (n, 2), its radius), in id order
_Tracks = tuple[tuple[str, np.ndarray, float], ...]


def _tracks(moving: Mapping[str, ObstacleObservation], t_ns: int, horizon_s: float) -> _Tracks:
    return tuple(
        (obstacle_id, predicted_track(obs, t_ns, horizon_s), obs.radius_m)
        for obstacle_id, obs in sorted(moving.items())
    )


def _gap_to_tracks(
    tracks: _Tracks, pose: tuple[float, float, float], footprint: Footprint, limit_m: float
) -> TrackGap:
    gap_m, nearest, reach_s, centre_m = math.inf, None, math.inf, math.inf
    for obstacle_id, track, radius_m in tracks:
        gaps = [disc_gap_m(pose, footprint, (float(px), float(py)), radius_m) for px, py in track]
        centre_m = min(
            centre_m, float(np.min(np.hypot(track[:, 0] - pose[0], track[:, 1] - pose[1]))) - radius_m
        )
        closest = min(gaps)
        if closest < gap_m:
            gap_m, nearest = closest, obstacle_id
        within = next((k for k, gap in enumerate(gaps) if gap < limit_m), None)
        if within is not None:
            reach_s = min(reach_s, within * PREDICTION_STEP_S)
    return TrackGap(gap_m, nearest, reach_s, centre_m)


@dataclass(frozen=True)
class BackOffStep:
    """What the back-off wants this tick: ``speed_mps`` (< 0 reversing, > 0 creeping forward, 0 holding)
    and ``detail`` (an event's text when something changed, else "")."""

    speed_mps: float
    detail: str

    @property
    def moving(self) -> bool:
        return self.speed_mps != 0.0


HOLD = BackOffStep(0.0, "")


@dataclass(frozen=True)
class _Scene:
    """What one tick's judgement looks at: the moving obstacles' tracks (predicted once a tick, then held
    against each pose it weighs) and the believed map."""

    tracks: _Tracks
    terrain: TerrainMap


class BackOff:
    """The back-off of one ``BLOCKED`` wait: started by a threat to the rover, bounded, then spent."""

    def __init__(
        self,
        footprint: Footprint,
        inflation_m: float,
        horizon_s: float,
        limits: YieldLimits = YieldLimits(),
        fence: Polygon = (),
    ) -> None:
        self._footprint = footprint
        self._limits = limits
        self._fence = fence  # [safety] fence (empty: none): the back-off never leaves it (way_blocked)
        self._inflation_m = inflation_m
        self._horizon_s = horizon_s
        self._start: tuple[int, float, float] | None = None  # (t_ns, x, y) where this wait's back-off began
        self._direction = 0.0  # -1 backing, +1 creeping forward, 0 not moving
        self._spent = False

    def reset(self) -> None:
        """A new wait: a new budget."""
        self._start = None
        self._direction = 0.0
        self._spent = False

    def step(
        self,
        t_ns: int,
        pose: tuple[float, float, float],
        moving: Mapping[str, ObstacleObservation],
        terrain: TerrainMap,
    ) -> BackOffStep:
        """Move out of a moving obstacle's predicted track while it reaches the footprint at ``pose``,
        within the bounds; hold otherwise."""
        if self._spent or self._limits.speed_mps <= 0.0:
            return HOLD
        scene = _Scene(_tracks(moving, t_ns, self._horizon_s), terrain)
        # Once moving, keep on until the track clears by the margin too (no stop-start at the edge).
        limit = self._inflation_m + (self._limits.margin_m if self._direction else 0.0)
        gap = self._gap(scene, pose)
        threat = gap.obstacle_id
        if threat is None or gap.gap_m >= limit:
            if not self._direction:
                return HOLD
            self._direction = 0.0
            return BackOffStep(0.0, "out of the way: the moving obstacles' tracks clear the rover; holding")
        x, y, _yaw = pose
        if self._start is None:
            self._start = (t_ns, x, y)
        started = not self._direction
        if started:
            self._direction = self._way_out(scene, pose, gap)
        bound = _bound_reached(self._start, t_ns, pose, self._limits) or self._blocked(scene, pose, gap)
        if not self._direction or bound:
            self._spent, self._direction = True, 0.0
            why = bound or (
                f"neither backing nor creeping forward {YIELD_LOOK_M:g} m is clear of the map and further "
                "from the track"
            )
            return BackOffStep(0.0, f"no back-off from moving obstacle {threat}: {why}; holding")
        detail = ""
        if started:
            way = "backing off" if self._direction < 0.0 else "creeping forward out of its way"
            detail = f"moving obstacle {threat} predicted to reach the rover: {way}"
        return BackOffStep(self._direction * self._limits.speed_mps, detail)

    def _way_out(self, scene: _Scene, pose: tuple[float, float, float], gap: TrackGap) -> float:
        """Back (the way it came) if that gets further from the tracks, else forward if that does, else 0:
        a rover whose rear is in the lane would only back further into it (a 1 m/s cart hit one so)."""
        for direction in (-1.0, 1.0):
            blocked = way_blocked(scene.terrain, pose, self._footprint, direction, self._fence)
            if not blocked and self._further(scene, moved_along(pose, direction * YIELD_LOOK_M), gap):
                return direction
        return 0.0

    def _blocked(self, scene: _Scene, pose: tuple[float, float, float], gap: TrackGap) -> str:
        """Why the rover may go no further its way ("" while it may)."""
        if not self._direction:
            return ""
        ahead = moved_along(pose, self._direction * YIELD_LOOK_M)
        blocked = way_blocked(scene.terrain, pose, self._footprint, self._direction, self._fence)
        if blocked:
            return blocked
        if not self._gap(scene, ahead).further_than(gap):
            return f"{YIELD_LOOK_M:g} m further would be no further from the track"
        return ""

    def _further(self, scene: _Scene, pose: tuple[float, float, float], gap: TrackGap) -> bool:
        """Whether ``pose`` is further than ``gap`` from the tracks."""
        return self._gap(scene, pose).further_than(gap)

    def _gap(self, scene: _Scene, pose: tuple[float, float, float]) -> TrackGap:
        return _gap_to_tracks(scene.tracks, pose, self._footprint, self._inflation_m)


def moved_along(pose: tuple[float, float, float], distance_m: float) -> tuple[float, float, float]:
    """``pose`` moved ``distance_m`` along its heading (negative: backwards)."""
    x, y, yaw = pose
    return (x + distance_m * math.cos(yaw), y + distance_m * math.sin(yaw), yaw)


def way_blocked(
    terrain: TerrainMap,
    pose: tuple[float, float, float],
    footprint: Footprint,
    direction: float,
    fence: Polygon = (),
) -> str:
    """Why the rover at ``pose`` may not move ``YIELD_LOOK_M`` along its heading (``direction`` -1: back,
    +1: on), "" when it may: the footprint there must be clear of ``terrain``'s obstacles and edge, and its
    centre inside ``fence`` (``[safety] fence``; empty: none), which the supervisor holds the estimated
    position to: outside, the rover would hold until it was back inside, stranded by its own move. The test
    every straight move off the path makes before and while it moves (this back-off, and backing out when
    dug in, ``navigator.recovery``)."""
    there = moved_along(pose, direction * YIELD_LOOK_M)
    if footprint_collides(terrain, there, footprint):
        return f"an obstacle or the map edge within {YIELD_LOOK_M:g} m"
    if fence and not inside_polygon(there[0], there[1], fence):
        return f"the geofence within {YIELD_LOOK_M:g} m"
    return ""


def _bound_reached(
    start: tuple[int, float, float], t_ns: int, pose: tuple[float, float, float], limits: YieldLimits
) -> str:
    """Why a back-off that began at ``start`` (t_ns, x, y) may go no further ("" while it may)."""
    start_ns, x0, y0 = start
    x, y, _yaw = pose
    moved_m = math.hypot(x - x0, y - y0)
    if moved_m >= limits.max_m:
        return f"{moved_m:.1f} m moved, the limit is {limits.max_m:g} m"
    elapsed_s = (t_ns - start_ns) * 1e-9
    if elapsed_s >= limits.max_s:
        return f"{elapsed_s:.1f} s moving, the limit is {limits.max_s:g} s"
    return ""
