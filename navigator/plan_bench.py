"""The planning benchmark: our compiled A* against pyastar2d and python-tcod on the same seeded maps.

Maps: ``size x size`` cells, integer costs uniform in 1..10, about 20 % obstacle cells, start and goal in
opposite corners (kept free). Each solver plans corner to corner ``repeats`` times; the median wall time
is reported (``time.perf_counter`` here is the benchmark's own stopwatch, not a component clock).

Solvers and the problem each solves (they differ in edge model, so costs are compared only where the
problem is the same):

* ``ours``: the planner's model, ``step * mean(cell costs)``, diagonal step sqrt 2, no corner cutting,
  optimal octile A*;
* ``ours_target``: our kernel on pyastar2d's own model (``cost of the entered cell``, diagonal step 1,
  corner cutting allowed, Chebyshev heuristic), so the costs must agree exactly with pyastar2d's;
* ``pyastar2d``: ``astar_path(..., allow_diagonal=True)`` (C++);
* ``tcod``: ``tcod.path.AStar(cost, diagonal=1.41)`` (libtcod, C; integer costs, 0 = wall);
* ``python``: our pure-Python heapq A* (same model as ``ours``), only on the smallest map (it is slow).

``repair``: a local change on the map (a 3 x 3 block of obstacles dropped on the current path near its
middle, and one beside it) and the plan repaired by ``navigator.replanning.RepairingPlanner`` (A* with the
goal's cost-to-go field as heuristic) against a fresh plan; the field's one-off cost is reported too.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from navigator import astar_kernel
from navigator.astar import PlanResult, astar
from navigator.astar_python import astar_python
from navigator.replanning import RepairingPlanner

DEFAULT_SIZES = (256, 1024, 2048)
OBSTACLE_FRACTION = 0.2


@dataclass
class SizeResult:
    size: int
    times_ms: dict[str, float] = field(default_factory=dict)
    expanded: dict[str, int] = field(default_factory=dict)
    costs: dict[str, float] = field(default_factory=dict)
    ratios: dict[str, float] = field(default_factory=dict)


def benchmark_map(size: int, seed: int) -> np.ndarray:
    """Integer costs 1..10 as float64 with ~20 % obstacle cells (inf); the two corners kept free."""
    rng = np.random.default_rng(seed)
    cost = rng.integers(1, 11, size=(size, size)).astype(np.float64)
    cost[rng.random((size, size)) < OBSTACLE_FRACTION] = np.inf
    # Keep each corner's 3 x 3 neighbourhood free so start and goal are not walled in by chance.
    cost[:3, :3] = np.minimum(cost[:3, :3], 10.0)
    cost[-3:, -3:] = np.minimum(cost[-3:, -3:], 10.0)
    return cost


def _median_ms(run: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    times = []
    result: Any = None
    for _ in range(repeats):
        began = time.perf_counter()
        result = run()
        times.append((time.perf_counter() - began) * 1e3)
    return statistics.median(times), result


def _ours_target(cost: np.ndarray) -> tuple[float, int]:
    rows, cols = cost.shape
    flat = np.ascontiguousarray(cost.ravel())
    _, goal_cost, expanded = astar_kernel.search(
        flat, cols, 0, rows * cols - 1, astar_kernel.H_OCTILE, 1.0, np.ones((8, 1)), False,
        astar_kernel.MODEL_TARGET, 1.0, False,
    )  # fmt: skip
    return float(goal_cost), int(expanded)


def _path_cost_target(cost: np.ndarray, path: np.ndarray) -> float:
    """pyastar2d's cost of a returned path: the sum of the entered cells' costs."""
    return float(cost[path[1:, 0], path[1:, 1]].sum())


def run_size(size: int, seed: int, repeats: int, with_python: bool) -> SizeResult:
    import pyastar2d
    import tcod.path

    cost = benchmark_map(size, seed)
    goal = (size - 1, size - 1)
    result = SizeResult(size)

    ms, plan = _median_ms(lambda: astar(cost, (0, 0), goal, "octile"), repeats)
    result.times_ms["ours"], result.expanded["ours"], result.costs["ours"] = ms, plan.expanded, plan.cost

    ms, (target_cost, target_expanded) = _median_ms(lambda: _ours_target(cost), repeats)
    result.times_ms["ours_target"] = ms
    result.expanded["ours_target"] = target_expanded
    result.costs["ours_target"] = target_cost

    weights = cost.astype(np.float32)
    ms, path = _median_ms(lambda: pyastar2d.astar_path(weights, (0, 0), goal, allow_diagonal=True), repeats)
    result.times_ms["pyastar2d"] = ms
    result.costs["pyastar2d"] = math.nan if path is None else _path_cost_target(cost, path)

    tcod_cost = np.where(np.isfinite(cost), cost, 0).astype(np.int32)

    def tcod_plan() -> list[tuple[int, int]]:
        return tcod.path.AStar(tcod_cost, diagonal=1.41).get_path(0, 0, size - 1, size - 1)

    ms, _ = _median_ms(tcod_plan, repeats)
    result.times_ms["tcod"] = ms

    if with_python:
        ms, plan = _median_ms(lambda: astar_python(cost, (0, 0), goal, "octile"), 1)
        result.times_ms["python"], result.expanded["python"] = ms, plan.expanded
        result.costs["python"] = plan.cost

    base = result.times_ms["pyastar2d"]
    result.ratios = {name: t / base for name, t in result.times_ms.items()}
    return result


def warm_up() -> None:
    """Compile the numba kernels (cached on disk after the first run) before anything is timed."""
    small = benchmark_map(16, 0)
    astar(small, (0, 0), (15, 15))
    _ours_target(small)
    RepairingPlanner(small).plan((0, 0), (15, 15))


def repair_figures(size: int, seed: int, repeats: int) -> dict[str, Any]:
    """Plan repair after a local change (3 x 3 obstacle block) on the path, and beside it, vs a fresh plan.

    The repair is ``navigator.replanning.RepairingPlanner`` (what ``Guidance`` uses): the goal's cost-to-go
    field is built once per goal (timed apart, ``field_ms``), then after the change the new costs are taken
    in (the O(cells) "did any cost fall" check) and A* runs with the field as its heuristic; both are in
    ``repair_ms``. The fresh plan is plain octile A* on the changed map; the costs must agree.
    """
    cost = benchmark_map(size, seed)
    start, goal = (0, 0), (size - 1, size - 1)
    fresh_ms, plan = _median_ms(lambda: astar(cost, start, goal, "octile"), repeats)
    mid_row, mid_col = plan.cells[len(plan.cells) // 2]
    on_path = cost.copy()
    on_path[max(mid_row - 1, 0) : mid_row + 2, max(mid_col - 1, 0) : mid_col + 2] = np.inf
    # A change away from the path: 10 cells off the path's middle, perpendicular-ish.
    beside = cost.copy()
    r, c = min(mid_row + 10, size - 2), max(mid_col - 10, 1)
    beside[r - 1 : r + 2, c - 1 : c + 2] = np.inf

    def field_once() -> RepairingPlanner:
        planner = RepairingPlanner(cost)
        planner.prepare(goal)
        return planner

    field_ms, planner = _median_ms(field_once, repeats)

    def repair(new_cost: np.ndarray) -> PlanResult:
        planner.update_costs(new_cost)
        return planner.plan(start, goal)

    figures: dict[str, Any] = {"size": size, "fresh_ms": fresh_ms, "fresh_expanded": plan.expanded}
    figures["field_ms"] = field_ms
    figures["field_ratio"] = field_ms / fresh_ms
    for key, changed in (("", on_path), ("off_path_", beside)):

        def repair_this(new_cost: np.ndarray = changed) -> PlanResult:
            return repair(new_cost)

        repair_ms, repaired = _median_ms(repair_this, repeats)
        fresh = astar(changed, start, goal, "octile")
        figures[f"{key}repair_ms"] = repair_ms
        figures[f"{key}ratio"] = repair_ms / fresh_ms
        figures[f"{key}repair_expanded"] = repaired.expanded
        figures[f"{key}same_cost"] = bool(abs(repaired.cost - fresh.cost) <= 1e-9 * fresh.cost)
    return figures
