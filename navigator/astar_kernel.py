"""The compiled A* search loop (numba): one function over flat arrays, no Python objects inside.

Kept apart from ``navigator.astar`` (validation, heuristics by name, path tracing) so the hot loop reads
as one piece. The open list is an *indexed* binary heap with decrease-key: every cell is in the heap at
most once, so the heap never holds stale entries (a lazy-deletion heap pushes up to 8 entries per cell)
and stays at most as large as the frontier.

Edge models (``model``):

* ``MODEL_MEAN`` (the planner's): ``step * (cost[a] + cost[b]) / 2 * factor[move, a]``;
* ``MODEL_TARGET``: ``step * cost[b]`` (the cost of the cell entered), the model of pyastar2d and
  libtcod, so the benchmark can solve *their* problem too and compare costs exactly.

``step`` is 1 for an orthogonal move and ``diagonal_step`` for a diagonal one. Heuristics (``heuristic``):
0 octile ``max + (diagonal_step - 1) * min``, 1 euclidean, 2 manhattan / sqrt 2; each times ``h_scale``
(the cheapest possible cost per cell of distance) and the weight.
"""

from __future__ import annotations

import math

import numba
import numpy as np

MODEL_MEAN = 0
MODEL_TARGET = 1

H_OCTILE = 0
H_EUCLIDEAN = 1
H_MANHATTAN = 2

_INV_SQRT2 = 1.0 / math.sqrt(2.0)

# Move m: (d_row, d_col); orthogonal first. ``navigator.costs.direction_factors`` uses the same order.
MOVES = np.array(
    [[-1, 0], [1, 0], [0, -1], [0, 1], [-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=np.int64
)  # fmt: skip


@numba.njit(cache=True, inline="always")
def _h(row: int, col: int, goal_row: int, goal_col: int, kind: int, diagonal_step: float) -> float:
    d_row = abs(row - goal_row)
    d_col = abs(col - goal_col)
    if kind == H_OCTILE:
        if d_row > d_col:
            return d_row + (diagonal_step - 1.0) * d_col
        return d_col + (diagonal_step - 1.0) * d_row
    if kind == H_EUCLIDEAN:
        return math.sqrt(float(d_row * d_row + d_col * d_col))
    return (d_row + d_col) * _INV_SQRT2


@numba.njit(cache=True, inline="always")
def _less(f: np.ndarray, g: np.ndarray, a: int, b: int) -> bool:
    # Ties on f go to the larger g (the cell nearer the goal), then to the smaller index: deterministic,
    # and on grids with many equal costs it stops A* from expanding every tied cell.
    if f[a] != f[b]:
        return f[a] < f[b]
    if g[a] != g[b]:
        return g[a] > g[b]
    return a < b


@numba.njit(cache=True)
def _sift_up(heap: np.ndarray, pos: np.ndarray, f: np.ndarray, g: np.ndarray, i: int) -> None:
    node = heap[i]
    while i > 0:
        parent = (i - 1) >> 1
        other = heap[parent]
        if not _less(f, g, node, other):
            break
        heap[i] = other
        pos[other] = i
        i = parent
    heap[i] = node
    pos[node] = i


@numba.njit(cache=True)
def _sift_down(heap: np.ndarray, pos: np.ndarray, f: np.ndarray, g: np.ndarray, i: int, size: int) -> None:
    node = heap[i]
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        if child + 1 < size and _less(f, g, heap[child + 1], heap[child]):
            child += 1
        other = heap[child]
        if not _less(f, g, other, node):
            break
        heap[i] = other
        pos[other] = i
        i = child
    heap[i] = node
    pos[node] = i


@numba.njit(cache=True)
def search(
    cost: np.ndarray,
    cols: int,
    start: int,
    goal: int,
    heuristic: int,
    h_scale: float,
    factors: np.ndarray,
    use_factors: bool,
    model: int,
    diagonal_step: float,
    no_corner_cutting: bool,
) -> tuple[np.ndarray, float, int]:
    """A* over a flat ``cost`` grid (row-major, ``cols`` wide). Returns (parent, goal cost, expanded).

    ``parent[i]`` is the predecessor of cell ``i`` on its cheapest known path (-1 for none); the goal cost
    is ``inf`` when the goal was not reached. ``factors``: ``(8, cells)`` direction factors (>= 1) for
    ``MODEL_MEAN`` when ``use_factors``; any array otherwise.
    """
    n = cost.size
    rows = n // cols
    g = np.full(n, np.inf)
    f = np.empty(n)
    parent = np.full(n, -1, dtype=np.int32)
    # pos >= 0: place in the heap; -1: never reached; -2: closed (expanded).
    pos = np.full(n, -1, dtype=np.int32)
    heap = np.empty(n, dtype=np.int32)
    goal_row, goal_col = goal // cols, goal % cols

    g[start] = 0.0
    f[start] = h_scale * _h(start // cols, start % cols, goal_row, goal_col, heuristic, diagonal_step)
    heap[0] = start
    pos[start] = 0
    size = 1
    expanded = 0
    while size > 0:
        index = heap[0]
        size -= 1
        if size > 0:
            heap[0] = heap[size]
            pos[heap[0]] = 0
            _sift_down(heap, pos, f, g, 0, size)
        pos[index] = -2
        expanded += 1
        if index == goal:
            return parent, g[goal], expanded
        row = index // cols
        col = index - row * cols
        here_cost = cost[index]
        here_g = g[index]
        for move in range(8):
            n_row = row + MOVES[move, 0]
            n_col = col + MOVES[move, 1]
            if n_row < 0 or n_row >= rows or n_col < 0 or n_col >= cols:
                continue
            n_index = n_row * cols + n_col
            if pos[n_index] == -2:
                continue
            n_cost = cost[n_index]
            if n_cost == np.inf:
                continue
            step = 1.0
            if move >= 4:
                if no_corner_cutting and (
                    cost[row * cols + n_col] == np.inf or cost[n_row * cols + col] == np.inf
                ):
                    continue
                step = diagonal_step
            if model == MODEL_MEAN:
                edge = step * 0.5 * (here_cost + n_cost)
                if use_factors:
                    edge *= factors[move, index]
            else:
                edge = step * n_cost
            tentative = here_g + edge
            if tentative < g[n_index]:
                g[n_index] = tentative
                parent[n_index] = index
                f[n_index] = tentative + h_scale * _h(
                    n_row, n_col, goal_row, goal_col, heuristic, diagonal_step
                )
                if pos[n_index] == -1:
                    heap[size] = n_index
                    pos[n_index] = size
                    size += 1
                _sift_up(heap, pos, f, g, pos[n_index])
    return parent, np.inf, expanded
