"""Pure-Python A* (heapq), the readable reference and a benchmark peer of the compiled search.

Same edge model and results as ``navigator.astar.astar`` without direction factors.

Edge cost between neighbouring cells a and b: ``step * (cost[a] + cost[b]) / 2`` with ``step`` 1 for an
orthogonal and sqrt(2) for a diagonal move (in cells). ``np.inf`` cells are never entered. A diagonal move
needs both orthogonal cells beside it traversable (no corner cutting past an obstacle).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from navigator.errors import NoPathError, PlanningError

SQRT2 = math.sqrt(2.0)
HEURISTICS = ("octile", "euclidean", "manhattan")

# (d_row, d_col, step length in cells)
_MOVES = (
    (-1, 0, 1.0), (1, 0, 1.0), (0, -1, 1.0), (0, 1, 1.0),
    (-1, -1, SQRT2), (-1, 1, SQRT2), (1, -1, SQRT2), (1, 1, SQRT2),
)  # fmt: skip


@dataclass(frozen=True)
class PlanResult:
    """Cells from start to goal inclusive, the summed edge cost, and how many cells were expanded."""

    cells: list[tuple[int, int]]
    cost: float
    expanded: int


def _heuristic(name: str, min_cost: float, goal: tuple[int, int]) -> Callable[[int, int], float]:
    """Lower bound of the cost to the goal: a distance in cells times the cheapest cell cost.

    * octile: the exact 8-connected distance on a uniform grid, ``max + (sqrt2 - 1) * min``;
    * euclidean: straight-line distance, never more than octile;
    * manhattan: ``(|dr| + |dc|) / sqrt2``. Plain Manhattan overestimates a diagonal move (2 vs sqrt2),
      so it is divided by sqrt2; then ``0.707 (dx + dy) <= max + 0.414 min`` holds for all dx, dy.
    All three are consistent, so a closed cell never needs reopening (with ``weight`` 1).
    """
    goal_row, goal_col = goal
    if name == "octile":

        def octile(row: int, col: int) -> float:
            d_row, d_col = abs(row - goal_row), abs(col - goal_col)
            return min_cost * (max(d_row, d_col) + (SQRT2 - 1.0) * min(d_row, d_col))

        return octile
    if name == "euclidean":

        def euclidean(row: int, col: int) -> float:
            return min_cost * math.hypot(row - goal_row, col - goal_col)

        return euclidean
    if name == "manhattan":

        def manhattan(row: int, col: int) -> float:
            return min_cost * (abs(row - goal_row) + abs(col - goal_col)) / SQRT2

        return manhattan
    raise PlanningError(f"unknown heuristic {name!r}; choose one of {', '.join(HEURISTICS)}")


def check_cell(cost: np.ndarray, cell: tuple[int, int], what: str) -> None:
    """Refuse a start or goal off the grid or on a lethal cell, with a message naming the cell."""
    rows, cols = cost.shape
    row, col = cell
    if not (0 <= row < rows and 0 <= col < cols):
        raise PlanningError(f"{what} cell {cell} is outside the {rows} x {cols} cost grid")
    if not math.isfinite(float(cost[row, col])):
        raise PlanningError(
            f"{what} cell {cell} is lethal (an obstacle, its inflation, or too steep); move the {what} "
            "or check the map"
        )


def astar_python(
    cost: np.ndarray,
    start: tuple[int, int],
    goal: tuple[int, int],
    heuristic: str = "octile",
    weight: float = 1.0,
) -> PlanResult:
    """Cheapest 8-connected path from ``start`` to ``goal`` (``(row, col)`` cells) over ``cost``.

    ``cost``: ``(rows, cols)`` float, finite values > 0 are traversable, ``np.inf`` is lethal.
    ``weight`` > 1 inflates the heuristic (weighted A*: faster, at most ``weight`` times the optimum).
    Raises PlanningError for a bad grid, a start/goal off the grid or lethal, NoPathError when none exists.
    """
    grid = np.asarray(cost, dtype=np.float64)
    if grid.ndim != 2 or grid.size == 0:
        raise PlanningError(f"cost grid must be a non-empty 2-D array, got shape {grid.shape}")
    if np.any(np.isnan(grid)) or np.any(grid <= 0.0):
        raise PlanningError("cost grid must hold costs > 0 or inf (lethal); found NaN or a value <= 0")
    if not (math.isfinite(weight) and weight >= 0.0):
        raise PlanningError(f"heuristic weight must be a finite number >= 0, got {weight}")
    start = (int(start[0]), int(start[1]))
    goal = (int(goal[0]), int(goal[1]))
    check_cell(grid, start, "start")
    check_cell(grid, goal, "goal")

    rows, cols = grid.shape
    finite = grid[np.isfinite(grid)]
    h = _heuristic(heuristic, float(finite.min()), goal)

    # Flat Python lists: element access on them is several times faster than on numpy arrays in this
    # per-cell loop (a later numba version can go back to arrays).
    flat_cost: list[float] = grid.ravel().tolist()
    g_score = [math.inf] * (rows * cols)
    closed = [False] * (rows * cols)
    parent = [-1] * (rows * cols)
    start_index = start[0] * cols + start[1]
    goal_index = goal[0] * cols + goal[1]
    g_score[start_index] = 0.0
    # Ties on f go to the cell nearer the goal (smaller h), then to the smaller index: deterministic.
    start_h = weight * h(*start)
    open_heap: list[tuple[float, float, int]] = [(start_h, start_h, start_index)]
    expanded = 0
    inf = math.inf

    while open_heap:
        _, _, index = heapq.heappop(open_heap)
        if closed[index]:
            continue  # a stale entry: this cell was reached cheaper already
        closed[index] = True
        expanded += 1
        if index == goal_index:
            return PlanResult(_trace(parent, goal_index, cols), g_score[goal_index], expanded)
        row, col = divmod(index, cols)
        here_cost = flat_cost[index]
        here_g = g_score[index]
        for d_row, d_col, step in _MOVES:
            n_row, n_col = row + d_row, col + d_col
            if not (0 <= n_row < rows and 0 <= n_col < cols):
                continue
            n_index = n_row * cols + n_col
            n_cost = flat_cost[n_index]
            if n_cost == inf or closed[n_index]:
                continue
            if (
                d_row
                and d_col
                and (flat_cost[row * cols + n_col] == inf or flat_cost[n_row * cols + col] == inf)
            ):
                continue  # no corner cutting
            tentative = here_g + step * 0.5 * (here_cost + n_cost)
            if tentative < g_score[n_index]:
                g_score[n_index] = tentative
                parent[n_index] = index
                n_h = weight * h(n_row, n_col)
                heapq.heappush(open_heap, (tentative + n_h, n_h, n_index))

    raise NoPathError(
        f"no traversable path from cell {start} to cell {goal} ({expanded} cells reachable from the start); "
        "the goal is walled off by obstacles or lethal slopes"
    )


def _trace(parent: list[int], goal_index: int, cols: int) -> list[tuple[int, int]]:
    cells: list[tuple[int, int]] = []
    index = goal_index
    while index != -1:
        cells.append(divmod(index, cols))
        index = parent[index]
    cells.reverse()
    return cells
