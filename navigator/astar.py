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

Two exact searches (``search``):

* ``"bucket"`` (``navigator.astar_bucket_kernel``): a bucket queue on ``f = g + alpha * octile * c_min``
  with buckets ``(1 - alpha) * c_min`` wide, each of which holds only final cells, so a push or a pop is
  O(1); ``alpha = BUCKET_ALPHA``. Only for the octile heuristic at weight 1;
* ``"heap"`` (``navigator.astar_kernel``): a binary heap with the full heuristic and ties toward the goal;
  any heuristic, any weight, the cost-to-go ``field`` of ``navigator.replanning``.

``"auto"`` (the default) takes the bucket search where it applies, except on a plateau (every finite
cost equal, no direction factors: f then ties exactly along many optimal paths, the heap's tie-break
walks one of them and the buckets would flood the ellipse below the goal's key) or when its ring of
buckets would be huge; the heap otherwise. Both return an optimal path (the same cost to float
tolerance; on ties the cells may differ). docs/planning.md has the measurements behind the choice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navigator import astar_bucket_kernel, astar_kernel
from navigator.astar_python import check_cell
from navigator.errors import NoPathError, PlanningError

SQRT2 = math.sqrt(2.0)
HEURISTICS = ("octile", "euclidean", "manhattan")
_HEURISTIC_IDS = {
    "octile": astar_kernel.H_OCTILE,
    "euclidean": astar_kernel.H_EUCLIDEAN,
    "manhattan": astar_kernel.H_MANHATTAN,
}
SEARCHES = ("auto", "bucket", "heap")
#: The bucket search's share of the octile heuristic: buckets are ``(1 - alpha) * c_min`` wide. On maps
#: where A* expands nearly every cell it hardly matters (0.5 and 0.75 within noise on the benchmark);
#: on near-uniform maps a higher alpha expands fewer cells, at more (cheap) buckets per unit of cost.
BUCKET_ALPHA = 0.75
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
    search: str = "auto",
) -> PlanResult:
    """Cheapest 8-connected path from ``start`` to ``goal`` (``(row, col)`` cells) over ``cost``.

    ``cost``: ``(rows, cols)`` float, finite values > 0 are traversable, ``np.inf`` is lethal.
    ``factors``: optional ``(8, rows, cols)`` direction factors (move order of ``astar_kernel.MOVES``).
    ``field``: optional ``(rows, cols)`` lower bounds of the cost to ``goal`` that replace the named
    heuristic (``navigator.replanning``: the cost-to-go of an earlier map whose costs were nowhere higher).
    ``search``: one of ``SEARCHES`` (module docstring); ``"bucket"`` with another heuristic, a weight
    other than 1 or a field is a PlanningError.
    Raises PlanningError for a bad grid, a start/goal off the grid or lethal, NoPathError when none exists.
    """
    if heuristic not in _HEURISTIC_IDS:
        raise PlanningError(f"unknown heuristic {heuristic!r}; choose one of {', '.join(HEURISTICS)}")
    if not (math.isfinite(weight) and weight >= 0.0):
        raise PlanningError(f"heuristic weight must be a finite number >= 0, got {weight}")
    if search not in SEARCHES:
        raise PlanningError(f"unknown search {search!r}; choose one of {', '.join(SEARCHES)}")
    bucket_applies = heuristic == "octile" and weight == 1.0 and field is None
    if search == "bucket" and not bucket_applies:
        raise PlanningError("the bucket search needs the octile heuristic at weight 1 and no field")
    if search != "heap" and bucket_applies:
        planned = _bucket_astar(cost, start, goal, factors, forced=search == "bucket")
        if planned is not None:
            return planned
    grid = check_cost_grid(cost)
    flat_factors = _NO_FACTORS if factors is None else check_factors(factors, grid.shape)
    start, goal = _checked_ends(grid, start, goal)
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
        raise _no_path(start, goal, expanded)
    return PlanResult(trace(parent, goal[0] * cols + goal[1], cols), float(goal_cost), int(expanded))


def _checked_ends(
    grid: np.ndarray, start: tuple[int, int], goal: tuple[int, int]
) -> tuple[tuple[int, int], tuple[int, int]]:
    start = (int(start[0]), int(start[1]))
    goal = (int(goal[0]), int(goal[1]))
    check_cell(grid, start, "start")
    check_cell(grid, goal, "goal")
    return start, goal


def _no_path(start: tuple[int, int], goal: tuple[int, int], expanded: int) -> NoPathError:
    return NoPathError(
        f"no traversable path from cell {start} to cell {goal} ({expanded} cells reachable from the "
        "start); the goal is walled off by obstacles or lethal slopes"
    )


def _bucket_astar(
    cost: np.ndarray,
    start: tuple[int, int],
    goal: tuple[int, int],
    factors: np.ndarray | None,
    forced: bool,
) -> PlanResult | None:
    """The bucket search, or None (not ``forced``) on a plateau or when its ring would be too large."""
    grid = np.ascontiguousarray(cost, dtype=np.float64)
    if grid.ndim != 2 or grid.size == 0:
        raise PlanningError(f"cost grid must be a non-empty 2-D array, got shape {grid.shape}")
    cols = grid.shape[1]
    # One pass pads the grid and validates it (the heap path's check_cost_grid, fused).
    frame, bad, c_min, c_max = astar_bucket_kernel.padded(grid.ravel(), cols)
    if bad:
        raise PlanningError("cost grid must hold costs > 0 or inf (lethal); found NaN or a value <= 0")
    start, goal = _checked_ends(grid, start, goal)
    max_factor = 1.0
    flat_factors = _NO_FACTORS
    if factors is not None:
        flat_factors = check_factors(factors, grid.shape)
        max_factor = float(np.max(flat_factors, initial=1.0, where=np.isfinite(flat_factors)))
    slots = astar_bucket_kernel.slots_needed(SQRT2 * c_max * max_factor, c_min, BUCKET_ALPHA, SQRT2)
    plateau = c_max == c_min and factors is None
    if not forced and (plateau or slots > astar_bucket_kernel.MAX_SLOTS):
        return None
    parent, goal_cost, expanded = astar_bucket_kernel.search(
        frame, cols, start[0] * cols + start[1], goal[0] * cols + goal[1], BUCKET_ALPHA, c_min, slots,
        flat_factors, factors is not None, astar_kernel.MODEL_MEAN, SQRT2, True,
    )  # fmt: skip
    if not math.isfinite(goal_cost):
        raise _no_path(start, goal, expanded)
    cells = trace(parent, (goal[0] + 1) * (cols + 2) + goal[1] + 1, cols + 2, border=1)
    return PlanResult(cells, float(goal_cost), int(expanded))


def trace(parent: np.ndarray, goal_index: int, cols: int, border: int = 0) -> list[tuple[int, int]]:
    """Cells from the search's start to ``goal_index`` following ``parent`` links.

    ``cols`` is the width of the grid ``parent`` indexes; ``border`` the frame around the map in it
    (1 for the bucket search's padded grid), taken off the returned ``(row, col)``.
    """
    indices: list[int] = []
    index = goal_index
    while index != -1:
        indices.append(index)
        index = int(parent[index])
    indices.reverse()
    return [(i // cols - border, i % cols - border) for i in indices]
