"""Planning as a job: new obstacles into the map, then a plan if one is needed, off the control thread.

A plan can take hundreds of milliseconds (the first to a goal builds its cost-to-go field; a new
obstacle recomputes the cost grid). ``Guidance`` therefore hands the work to an ``Executor`` as a
``PlanRequest`` and keeps following its last path (or holds, with none) until the ``PlanOutcome`` is in:

* real time: ``plan_worker()``, one worker thread (the A* kernels release the GIL while they search);
* lockstep HIL and tests: ``InlineExecutor``, which runs the job inside ``submit``, so the outcome is
  there within the same tick and a trial stays deterministic, through the same interface.

While a job is in flight it owns the ``Planner``: nothing else mutates it (the control thread only reads
the terrain's elevation and classes, which planning never changes).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from navigator.errors import NoPathError, PlanningError, TerrainError
from navigator.perception import ObstacleObservation
from navigator.planner import Path, Planner
from navigator.terrain import TerrainMap, disc_mask

T = TypeVar("T")


class InlineExecutor(Executor):
    """Runs each job at ``submit``, on the caller's thread; the returned future is already done."""

    def submit(self, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> Future[T]:
        future: Future[T] = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as err:  # the caller reads it from the future, as from a worker's
            future.set_exception(err)
        return future


def plan_worker() -> ThreadPoolExecutor:
    """One planning thread: jobs run one at a time, in order."""
    return ThreadPoolExecutor(max_workers=1, thread_name_prefix="planner")


@dataclass(frozen=True)
class PlanRequest:
    """What to do: absorb ``new_obstacles`` (static, within sensing range) and plan if needed.

    ``path``: the path being followed, to judge whether the new obstacles touch it. ``must_plan``: plan
    whatever the obstacles do (a new goal, the rover off its path). ``retry_no_path``: the last plan found
    no path, so new obstacles are a reason to try again (costs changed). ``generation`` identifies the
    goal the request was made for (a newer goal makes its outcome's path stale).
    """

    generation: int
    start_xy: tuple[float, float]
    goal: tuple[float, float] | None
    new_obstacles: tuple[ObstacleObservation, ...]
    path: Path | None
    must_plan: bool
    retry_no_path: bool
    why: str = ""
    # Obstacles once seen standing, put in the map, and since seen moving: taken off the map, which is
    # rebuilt as given plus ``static_obstacles`` (every obstacle guidance still holds static, new ones too).
    moved_off: tuple[str, ...] = ()
    static_obstacles: tuple[ObstacleObservation, ...] = ()


@dataclass(frozen=True)
class PlanOutcome:
    generation: int
    details: tuple[str, ...]
    planned: bool  # a plan was attempted: ``path`` replaces the one followed (None: no path)
    path: Path | None
    repair_kept: bool  # obstacles were added and the followed path is still clear and optimal


def run_plan_request(planner: Planner, request: PlanRequest) -> PlanOutcome:
    """Do ``request`` on ``planner`` (on whichever thread the executor runs it)."""
    details: list[str] = []
    must_plan = request.must_plan
    repair_kept = False
    changed = _update_map(planner, request)
    if request.moved_off:
        # Costs fell where they stood: the path around them may no longer be the best one, and a goal that
        # had no path may have one now.
        must_plan |= request.goal is not None
        details.append(f"obstacles {', '.join(request.moved_off)} moved on: taken off the map")
    if request.new_obstacles:
        ids = ", ".join(o.obstacle_id for o in request.new_obstacles)
        if changed is None or request.path is None or request.goal is None or request.moved_off:
            # (``changed`` is set whenever obstacles are new.) With some taken off in the same update,
            # costs fell too: the plan is remade whatever the new ones touch.
            must_plan |= request.goal is not None and request.retry_no_path
            details.append(f"obstacles {ids} added to the map")
        elif path_touches(planner, request.path, changed, request.start_xy):
            must_plan = True
            details.append(f"obstacles {ids} block the path: replanning")
        else:
            repair_kept = True
            details.append(f"obstacles {ids} added; the path is clear of them and still optimal")
    if not must_plan or request.goal is None:
        return PlanOutcome(request.generation, tuple(details), False, None, repair_kept)
    try:
        path = planner.plan(request.start_xy, request.goal)
    except NoPathError as err:
        details.append(f"no path: {err}")
        return PlanOutcome(request.generation, tuple(details), True, None, repair_kept)
    except PlanningError as err:
        details.append(f"cannot plan: {err}")
        return PlanOutcome(request.generation, tuple(details), True, None, repair_kept)
    reason = f" ({request.why})" if request.why else ""
    details.append(f"planned {path.length_m:.1f} m, cost {path.cost:.1f}{reason}")
    return PlanOutcome(request.generation, tuple(details), True, path, repair_kept)


def _update_map(planner: Planner, request: PlanRequest) -> np.ndarray | None:
    """Put the request's obstacle changes into the planner's map in one cost update; returns where the
    cost changed (None: nothing to change). Obstacles that moved on are taken off by resetting the map to
    the given one plus ``static_obstacles``, with the new ones in the same mask: one update, not a reset
    and then an addition (each is a cost update)."""
    if request.moved_off:
        mask = _discs(planner.terrain, (*request.static_obstacles, *request.new_obstacles))
        return planner.reset_obstacles(mask)
    if request.new_obstacles:
        return planner.update_obstacles(_discs(planner.terrain, request.new_obstacles))
    return None


def _discs(terrain: TerrainMap, observations: Iterable[ObstacleObservation]) -> np.ndarray:
    """The cells the observed obstacles' discs cover (bool, map shape)."""
    mask = np.zeros(terrain.shape, dtype=bool)
    for obs in observations:
        mask |= disc_mask(terrain, obs.x, obs.y, obs.radius_m)
    return mask


def path_touches(planner: Planner, path: Path, changed: np.ndarray, xy: tuple[float, float]) -> bool:
    """Whether the rest of ``path`` (from the point nearest ``xy``) crosses a cell whose cost changed."""
    terrain = planner.terrain
    points = path.points
    start = int(np.argmin(np.hypot(points[:, 0] - xy[0], points[:, 1] - xy[1])))
    for px, py in points[max(start - 1, 0) :]:
        try:
            if changed[terrain.cell_of(float(px), float(py))]:
                return True
        except TerrainError:
            continue
    return False


def in_range(obs: ObstacleObservation, xy: tuple[float, float], range_m: float) -> bool:
    """Whether the obstacle's edge is within ``range_m`` of ``xy``."""
    return math.hypot(obs.x - xy[0], obs.y - xy[1]) - obs.radius_m <= range_m
