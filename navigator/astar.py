"""A* on a dense 8-connected cost grid: validation and path tracing around the compiled search.

Edge cost from cell a to its neighbour b by move m (the planner's model, exactly)::

    edge(a, b) = step(m) * (cost[a] + cost[b]) / 2 * factor[m, a]

with ``step`` 1 for an orthogonal and sqrt(2) for a diagonal move (in cells) and ``factor`` the optional
direction factor (>= 1; 1 when none is given; ``inf`` forbids that move). ``np.inf`` cells are never
entered. A diagonal move needs both orthogonal cells beside it traversable (no corner cutting past an
obstacle). The path cost is the sum of its edges; the planner multiplies it by the map resolution.

Heuristics, each a lower bound on the cost still to go (``c_min`` = the cheapest finite cell cost; every
factor is >= 1, so every move costs at least ``step * c_min``):

* octile: ``c_min * (max + (sqrt2 - 1) * min)`` of the row/column offsets, the exact 8-connected
  distance on a uniform grid (the tightest of the three);
* euclidean: ``c_min * hypot``, never more than octile;
* manhattan: ``c_min * (|dr| + |dc|) / sqrt2``. Plain Manhattan overestimates a diagonal move (2 vs
  sqrt2), so it is divided by sqrt2; then ``0.707 (dx + dy) <= max + 0.414 min`` holds for all dx, dy.

All three are consistent, so with ``weight`` 1 the search never reopens a cell and returns an optimal
path. ``weight`` w > 1 inflates the heuristic: the cost is then at most w times the optimum.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navigator import astar_kernel
from navigator.astar_python import check_cell
from navigator.errors import NoPathError, PlanningError

SQRT2 = math.sqrt(2.0)
HEURISTICS = ("octile", "euclidean", "manhattan")
_HEURISTIC_IDS = {
    "octile": astar_kernel.H_OCTILE,
    "euclidean": astar_kernel.H_EUCLIDEAN,
    "manhattan": astar_kernel.H_MANHATTAN,
}
_NO_FACTORS = np.ones((8, 1))
_NO_FIELD = np.zeros(1)


@dataclass(frozen=True)
class PlanResult:
    """Cells from start to goal inclusive, the summed edge cost, and how many cells were expanded."""

    cells: list[tuple[int, int]]
    cost: float
    expanded: int


def check_cost_grid(cost: np.ndarray) -> np.ndarray:
    """The grid as contiguous float64; PlanningError for a bad shape, NaN or a cost <= 0."""
    grid = np.ascontiguousarray(cost, dtype=np.float64)
    if grid.ndim != 2 or grid.size == 0:
        raise PlanningError(f"cost grid must be a non-empty 2-D array, got shape {grid.shape}")
    if np.any(np.isnan(grid)) or np.any(grid <= 0.0):
        raise PlanningError("cost grid must hold costs > 0 or inf (lethal); found NaN or a value <= 0")
    return grid


def check_factors(factors: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Direction factors as a contiguous ``(8, rows * cols)`` float64 array; each >= 1 or inf."""
    array = np.asarray(factors, dtype=np.float64)
    if array.shape != (8, *shape):
        raise PlanningError(
            f"direction factors must have shape (8, {shape[0]}, {shape[1]}), got {array.shape}"
        )
    if np.any(np.isnan(array)) or np.any(array < 1.0):
        raise PlanningError("direction factors must be >= 1 (or inf to forbid a move); found NaN or < 1")
    return np.ascontiguousarray(array.reshape(8, -1))


def _min_finite(grid: np.ndarray) -> float:
    # The grid is validated (> 0 or inf) and start and goal are finite, so the minimum exists.
    finite_min = float(np.min(grid, initial=np.inf, where=np.isfinite(grid)))
    return finite_min


def _check_field(field: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    array = np.asarray(field, dtype=np.float64)
    if array.shape != shape:
        raise PlanningError(f"heuristic field must have the grid's shape {shape}, got {array.shape}")
    if np.any(np.isnan(array)) or np.any(array < 0.0):
        raise PlanningError("heuristic field must hold lower bounds >= 0 (or inf); found NaN or < 0")
    return np.ascontiguousarray(array.ravel())


def astar(
    cost: np.ndarray,
    start: tuple[int, int],
    goal: tuple[int, int],
    heuristic: str = "octile",
    weight: float = 1.0,
    factors: np.ndarray | None = None,
    field: np.ndarray | None = None,
) -> PlanResult:
    """Cheapest 8-connected path from ``start`` to ``goal`` (``(row, col)`` cells) over ``cost``.

    ``cost``: ``(rows, cols)`` float, finite values > 0 are traversable, ``np.inf`` is lethal.
    ``factors``: optional ``(8, rows, cols)`` direction factors (move order of ``astar_kernel.MOVES``).
    ``field``: optional ``(rows, cols)`` lower bounds of the cost to ``goal`` that replace the named
    heuristic (``navigator.replanning``: the cost-to-go of an earlier map whose costs were nowhere higher).
    Raises PlanningError for a bad grid, a start/goal off the grid or lethal, NoPathError when none exists.
    """
    grid = check_cost_grid(cost)
    if heuristic not in _HEURISTIC_IDS:
        raise PlanningError(f"unknown heuristic {heuristic!r}; choose one of {', '.join(HEURISTICS)}")
    if not (math.isfinite(weight) and weight >= 0.0):
        raise PlanningError(f"heuristic weight must be a finite number >= 0, got {weight}")
    flat_factors = _NO_FACTORS if factors is None else check_factors(factors, grid.shape)
    start = (int(start[0]), int(start[1]))
    goal = (int(goal[0]), int(goal[1]))
    check_cell(grid, start, "start")
    check_cell(grid, goal, "goal")
    cols = grid.shape[1]
    if field is None:
        heuristic_id, h_scale, h_field = _HEURISTIC_IDS[heuristic], weight * _min_finite(grid), _NO_FIELD
    else:
        heuristic_id, h_scale, h_field = astar_kernel.H_FIELD, weight, _check_field(field, grid.shape)
    parent, goal_cost, expanded = astar_kernel.search(
        grid.ravel(),
        cols,
        start[0] * cols + start[1],
        goal[0] * cols + goal[1],
        heuristic_id,
        h_scale,
        flat_factors,
        factors is not None,
        astar_kernel.MODEL_MEAN,
        SQRT2,
        True,
        h_field,
    )
    if not math.isfinite(goal_cost):
        raise NoPathError(
            f"no traversable path from cell {start} to cell {goal} ({expanded} cells reachable from the "
            "start); the goal is walled off by obstacles or lethal slopes"
        )
    return PlanResult(trace(parent, goal[0] * cols + goal[1], cols), float(goal_cost), int(expanded))


def trace(parent: np.ndarray, goal_index: int, cols: int) -> list[tuple[int, int]]:
    """Cells from the search's start to ``goal_index`` following ``parent`` links."""
    indices: list[int] = []
    index = goal_index
    while index != -1:
        indices.append(index)
        index = int(parent[index])
    indices.reverse()
    return [(i // cols, i % cols) for i in indices]
