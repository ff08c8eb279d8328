"""The planning benchmark: our compiled A* against pyastar2d and python-tcod on the same seeded maps.

Maps: ``size x size`` cells, integer costs uniform in 1..10, about 20 % obstacle cells, start and goal in
opposite corners (kept free). Each solver plans corner to corner ``repeats`` times; the median wall time
is reported (``time.perf_counter`` here is the benchmark's own stopwatch, not a component clock).

Solvers and the problem each solves (they differ in edge model, so costs are compared only where the
problem is the same):

* ``ours``: ``navigator.astar.astar`` as the planner calls it: the planner's model, ``step * mean(cell
  costs)``, diagonal step sqrt 2, no corner cutting, optimal, octile; ``search="auto"`` (the bucket
  search on these maps);
* ``ours_heap``: the same problem with ``search="heap"`` (binary heap, full octile heuristic);
* ``ours_target``: our bucket kernel on pyastar2d's own model (``cost of the entered cell``, diagonal
  step 1, corner cutting allowed, Chebyshev heuristic), so its cost must equal pyastar2d's;
* ``pyastar2d``: ``astar_path(..., allow_diagonal=True)`` (C++);
* ``tcod``: ``tcod.path.AStar(cost, diagonal=1.41)`` (libtcod, C; integer costs, 0 = wall);
* ``python``: our pure-Python heapq A* (same model as ``ours``), only on the smallest map (it is slow).

Optimality is checked, not assumed: ``reference`` is scipy's Dijkstra (``scipy.sparse.csgraph``) over the
planner's edges built independently here with numpy; ``ours``, ``ours_heap`` and ``python`` must match it
and ``ours_target`` must match pyastar2d, each to a relative 1e-9 (``checks``).

``repair``: a local change on the map (a 3 x 3 block of obstacles dropped on the current path near its
middle, and one beside it) and the plan repaired by ``navigator.replanning.RepairingPlanner`` (A* with the
goal's cost-to-go field as heuristic) against a fresh plan; the field's one-off cost is reported too. Each
repair is timed twice: given the new grid alone (the whole grid checked for costs that fell and copied)
and given the changed block's window too, as ``Planner`` passes the windows of an obstacle update.

``obstacle update``: one rock seen on a procedural terrain map (0.25 m cells, 20 rocks on it already): the
cost grid made anew (inflation and distance transform over the whole map, the ground cost kept: what a
planner did per update before) against ``CostModel.update_grid`` (only the window the rock reaches), in
the same run; the grids must be equal bit for bit.
"""

from __future__ import annotations

import copy
import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from navigator import astar_bucket_kernel, astar_kernel
from navigator.astar import BUCKET_ALPHA, SQRT2, PlanResult, astar
from navigator.astar_python import astar_python
from navigator.costs import CostModel
from navigator.replanning import RepairingPlanner
from navigator.terrain import disc_mask, procedural
from navigator.vehicle import VehicleParams

OBSTACLE_FRACTION = 0.2
COST_TOLERANCE = 1e-9  # relative; sums of ~10^4 edges in a different order differ in the last bits


@dataclass
class SizeResult:
    size: int
    times_ms: dict[str, float] = field(default_factory=dict)
    expanded: dict[str, int] = field(default_factory=dict)
    costs: dict[str, float] = field(default_factory=dict)
    ratios: dict[str, float] = field(default_factory=dict)
    checks: dict[str, bool] = field(default_factory=dict)


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


def _median_ms_each_fresh(
    setup: Callable[[], Any], run: Callable[[Any], Any], repeats: int
) -> tuple[float, Any]:
    """``_median_ms`` of ``run(setup())``, each run on a fresh ``setup()`` that is not timed."""
    times = []
    result: Any = None
    for _ in range(repeats):
        subject = setup()
        began = time.perf_counter()
        result = run(subject)
        times.append((time.perf_counter() - began) * 1e3)
    return statistics.median(times), result


def _ours_target(cost: np.ndarray) -> tuple[float, int]:
    """Our bucket kernel on pyastar2d's problem (entered-cell cost, diagonal step 1, corners cut)."""
    rows, cols = cost.shape
    frame, _, c_min, c_max = astar_bucket_kernel.padded(np.ascontiguousarray(cost.ravel()), cols)
    slots = astar_bucket_kernel.slots_needed(c_max, c_min, BUCKET_ALPHA, 1.0)
    _, goal_cost, expanded = astar_bucket_kernel.search(
        frame, cols, 0, rows * cols - 1, BUCKET_ALPHA, c_min, slots, np.ones((8, 1)), False,
        astar_kernel.MODEL_TARGET, 1.0, False,
    )  # fmt: skip
    return float(goal_cost), int(expanded)


def reference_cost(cost: np.ndarray, start: tuple[int, int], goal: tuple[int, int]) -> float:
    """scipy's Dijkstra over the planner's edges (``navigator.astar``'s model), built here with numpy."""
    rows, cols = cost.shape
    index = np.arange(rows * cols, dtype=np.int32).reshape(rows, cols)
    finite = np.isfinite(cost)
    sources, targets, weights = [], [], []
    for d_row, d_col in astar_kernel.MOVES.tolist():
        here = (slice(max(0, -d_row), rows - max(0, d_row)), slice(max(0, -d_col), cols - max(0, d_col)))
        there = (slice(max(0, d_row), rows - max(0, -d_row)), slice(max(0, d_col), cols - max(0, -d_col)))
        allowed = finite[here] & finite[there]
        if d_row and d_col:  # no corner cutting: both orthogonal cells beside the move finite
            allowed &= finite[there[0], here[1]] & finite[here[0], there[1]]
        step = SQRT2 if d_row and d_col else 1.0
        sources.append(index[here][allowed])
        targets.append(index[there][allowed])
        weights.append(step * 0.5 * (cost[here][allowed] + cost[there][allowed]))
    graph = csr_matrix(
        (np.concatenate(weights), (np.concatenate(sources), np.concatenate(targets))),
        shape=(rows * cols, rows * cols),
    )
    distances = dijkstra(graph, indices=start[0] * cols + start[1])
    return float(distances[goal[0] * cols + goal[1]])


def _same(a: float, b: float) -> bool:
    return math.isclose(a, b, rel_tol=COST_TOLERANCE)


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

    ms, plan = _median_ms(lambda: astar(cost, (0, 0), goal, "octile", search="heap"), repeats)
    result.times_ms["ours_heap"], result.expanded["ours_heap"] = ms, plan.expanded
    result.costs["ours_heap"] = plan.cost

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

    result.costs["reference"] = reference_cost(cost, (0, 0), goal)
    for name in ("ours", "ours_heap", "python"):
        if name in result.costs:
            result.checks[f"{name} = reference"] = _same(result.costs[name], result.costs["reference"])
    result.checks["ours_target = pyastar2d"] = _same(result.costs["ours_target"], result.costs["pyastar2d"])

    base = result.times_ms["pyastar2d"]
    result.ratios = {name: t / base for name, t in result.times_ms.items()}
    return result


def warm_up() -> None:
    """Compile the numba kernels (cached on disk after the first run) before anything is timed."""
    small = benchmark_map(16, 0)
    astar(small, (0, 0), (15, 15))
    astar(small, (0, 0), (15, 15), search="heap")
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
    on_path_window = (max(mid_row - 1, 0), mid_row + 2, max(mid_col - 1, 0), mid_col + 2)
    on_path[on_path_window[0] : on_path_window[1], on_path_window[2] : on_path_window[3]] = np.inf
    # A change away from the path: 10 cells off the path's middle, perpendicular-ish.
    beside = cost.copy()
    r, c = min(mid_row + 10, size - 2), max(mid_col - 10, 1)
    beside_window = (r - 1, r + 2, c - 1, c + 2)
    beside[r - 1 : r + 2, c - 1 : c + 2] = np.inf

    def field_once() -> RepairingPlanner:
        planner = RepairingPlanner(cost)
        planner.prepare(goal)
        return planner

    field_ms, prepared = _median_ms(field_once, repeats)

    def planner_before_the_change() -> RepairingPlanner:
        # Each timed repair takes the change into a planner on the map before it (the field built there):
        # one that had taken it already would have nothing left to take, whatever it was told.
        return copy.deepcopy(prepared)

    figures: dict[str, Any] = {"size": size, "fresh_ms": fresh_ms, "fresh_expanded": plan.expanded}
    figures["field_ms"] = field_ms
    figures["field_ratio"] = field_ms / fresh_ms
    for key, changed, window in (("", on_path, on_path_window), ("off_path_", beside, beside_window)):

        def repair_this(planner: RepairingPlanner, new_cost: np.ndarray = changed) -> PlanResult:
            planner.update_costs(new_cost)
            return planner.plan(start, goal)

        def repair_in_window(
            planner: RepairingPlanner,
            new_cost: np.ndarray = changed,
            where: tuple[int, int, int, int] = window,
        ) -> PlanResult:
            planner.update_costs(new_cost, windows=[where])
            return planner.plan(start, goal)

        repair_ms, repaired = _median_ms_each_fresh(planner_before_the_change, repair_this, repeats)
        window_ms, in_window = _median_ms_each_fresh(planner_before_the_change, repair_in_window, repeats)
        fresh = astar(changed, start, goal, "octile")
        figures[f"{key}repair_ms"] = repair_ms
        figures[f"{key}ratio"] = repair_ms / fresh_ms
        # Told where the costs changed (as Planner tells it after an obstacle update): no O(cells) check.
        figures[f"{key}window_repair_ms"] = window_ms
        figures[f"{key}window_same_cost"] = bool(abs(in_window.cost - fresh.cost) <= 1e-9 * fresh.cost)
        figures[f"{key}repair_expanded"] = repaired.expanded
        figures[f"{key}same_cost"] = bool(abs(repaired.cost - fresh.cost) <= 1e-9 * fresh.cost)
    return figures


def obstacle_update_figures(size: int, seed: int, repeats: int) -> dict[str, Any]:
    """One rock added to a ``size`` x ``size`` map at 0.25 m: the cost grid made anew vs updated in place.

    Both keep the ground cost (class, slope, roughness), as the planner does; ``full_ms`` is
    ``CostModel.grid`` (whole-map dilation and distance transform), ``update_ms`` is
    ``CostModel.update_grid`` on a copy of the grid before the rock (the copy is not timed).
    """
    rng = np.random.default_rng(seed)
    params, model = VehicleParams(), CostModel()
    terrain = procedural((size, size), 0.25, rng, hill_count=8, class_patch_count=8)
    side_m = size * 0.25
    rocks = np.zeros(terrain.shape, dtype=bool)
    for x, y, radius in rng.uniform((0.0, 0.0, 0.3), (side_m, side_m, 1.5), (20, 3)).tolist():
        rocks |= disc_mask(terrain, x, y, radius)
    before = terrain.with_obstacles(rocks)
    after = before.with_obstacles(disc_mask(terrain, side_m / 2, side_m / 2, 1.0))
    ground = model.ground_cost(terrain, params)
    cost = model.grid(before, params, ground=ground)
    full_ms, full = _median_ms(lambda: model.grid(after, params, ground=ground), repeats)
    times = []
    for _ in range(repeats):
        updated = cost.copy()
        began = time.perf_counter()
        model.update_grid(updated, after, params, ground, before.obstacles)
        times.append((time.perf_counter() - began) * 1e3)
    update_ms = statistics.median(times)
    return {
        "size": size,
        "full_ms": full_ms,
        "update_ms": update_ms,
        "ratio": update_ms / full_ms,
        "same_grid": bool(np.array_equal(updated, full)),
    }
