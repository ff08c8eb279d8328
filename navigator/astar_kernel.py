"""The compiled A* search loop (numba): one function over flat arrays, no Python objects inside.

Kept apart from ``navigator.astar`` (validation, heuristics by name, path tracing) so the hot loop reads
as one piece. What makes it fast (on maps where the heuristic is weak A* expands most cells, so the cost
per expanded cell is what counts):

* the open list is a binary heap whose entries carry their keys *inline* (``f``, ``g``, cell index):
  a comparison touches the heap's own memory, never the per-cell arrays at random places; a pop walks
  the hole down to a leaf (one comparison per level) and sifts the last entry up from there.
  Entries are lazily deleted: an improved cell is pushed again and its stale entry skipped when popped.
  The order is total (``f``, then the larger ``g``, then the smaller index), so the expansion order is
  exactly that of a decrease-key heap with the same ties;
* ties on ``f`` go to the larger ``g`` (the cell nearer the goal): on grids with many equal costs this
  stops A* from expanding every tied cell;
* per cell one ``(cost, g)`` record, so a neighbour's two reads share a cache line; a closed cell holds
  ``-g``, so ``tentative < g`` fails for it without a separate closed array;
* the neighbour offsets are precomputed flat-index steps; cells away from the border skip bounds checks.

Edge models (``model``):

* ``MODEL_MEAN`` (the planner's): ``step * (cost[a] + cost[b]) / 2 * factor[move, a]``;
* ``MODEL_TARGET``: ``step * cost[b]`` (the cost of the cell entered), the model of pyastar2d and
  libtcod, so the benchmark can solve *their* problem too and compare costs exactly.

``step`` is 1 for an orthogonal move and ``diagonal_step`` for a diagonal one. Heuristics (``heuristic``):
0 octile ``max + (diagonal_step - 1) * min``, 1 euclidean, 2 manhattan / sqrt 2, each times ``h_scale``
(the cheapest possible cost per cell of distance, times the weight); 3 ``H_FIELD``: ``h_scale *
h_field[cell]``, a per-cell lower bound of the cost to the goal (``navigator.replanning`` passes the exact
cost-to-go of an earlier map whose costs were nowhere higher).
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
H_FIELD = 3

_INV_SQRT2 = 1.0 / math.sqrt(2.0)
_NO_FIELD = np.zeros(1)

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


@numba.njit(cache=True, error_model="numpy", inline="always")
def _before(f_a: float, g_a: float, i_a: int, f_b: float, g_b: float, i_b: int) -> bool:
    # Ties on f go to the larger g (nearer the goal), then to the smaller index: a total order, so runs
    # are deterministic and the lazy heap pops cells in the same order as a decrease-key heap would.
    if f_a < f_b:
        return True
    if f_a > f_b:
        return False
    if g_a != g_b:
        return g_a > g_b
    return i_a < i_b


@numba.njit(cache=True, error_model="numpy", inline="always")
def _sift_up(hf: np.ndarray, hg: np.ndarray, hc: np.ndarray, i: int, f: float, g: float, cell: int) -> None:
    """Put the entry ``(f, g, cell)`` into the hole at ``i`` and move it up to its place."""
    while i > 0:
        parent = (i - 1) >> 1
        if not _before(f, g, cell, hf[parent], hg[parent], hc[parent]):
            break
        hf[i] = hf[parent]
        hg[i] = hg[parent]
        hc[i] = hc[parent]
        i = parent
    hf[i] = f
    hg[i] = g
    hc[i] = cell


@numba.njit(cache=True, error_model="numpy")
def _grown_heap(
    hf: np.ndarray, hg: np.ndarray, hc: np.ndarray, size: int, capacity: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The heap's three arrays copied into new ones of ``capacity`` entries (the first ``size`` kept)."""
    grown_f = np.empty(capacity)
    grown_g = np.empty(capacity)
    grown_c = np.empty(capacity, dtype=np.int32)
    # A loop, not slice assignments: those compile numba's shape-mismatch message (seconds of a cold start).
    for i in range(size):
        grown_f[i] = hf[i]
        grown_g[i] = hg[i]
        grown_c[i] = hc[i]
    return grown_f, grown_g, grown_c


@numba.njit(cache=True, error_model="numpy")
def _pop(hf: np.ndarray, hg: np.ndarray, hc: np.ndarray, size: int) -> int:
    """Remove the top entry (read it first); returns the new size."""
    size -= 1
    if size == 0:
        return 0
    i = 0
    while True:  # walk the hole at the root down along the smaller child
        child = 2 * i + 1
        if child >= size:
            break
        right = child + 1
        if right < size and _before(hf[right], hg[right], hc[right], hf[child], hg[child], hc[child]):
            child = right
        hf[i] = hf[child]
        hg[i] = hg[child]
        hc[i] = hc[child]
        i = child
    _sift_up(hf, hg, hc, i, hf[size], hg[size], hc[size])
    return size


# nogil: in real time the search runs on the planner thread (navigator.plan_worker) and the control
# thread must keep ticking meanwhile.
@numba.njit(cache=True, error_model="numpy", nogil=True)
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
    h_field: np.ndarray = _NO_FIELD,
) -> tuple[np.ndarray, float, int]:
    """A* over a flat ``cost`` grid (row-major, ``cols`` wide). Returns (parent, goal cost, expanded).

    ``parent[i]`` is the predecessor of cell ``i`` on its cheapest known path (only meaningful for cells
    the search reached; the start's is -1); the goal cost is ``inf`` when the goal was not reached.
    ``factors``: ``(8, cells)`` direction factors (>= 1) for ``MODEL_MEAN`` when ``use_factors``; any
    array otherwise. ``h_field``: ``(cells,)`` lower bounds for ``H_FIELD``; any array otherwise.
    """
    n = cost.size
    rows = n // cols
    # node[i] = (cost, g): one cache line serves both reads of a neighbour. A closed cell holds -g, so
    # "tentative < g" is false for it without a separate closed array.
    node = np.empty((n, 2))
    for i in range(n):
        node[i, 0] = cost[i]
        node[i, 1] = np.inf
    parent = np.empty(n, dtype=np.int32)
    capacity = max(1024, n // 8)
    hf = np.empty(capacity)
    hg = np.empty(capacity)
    hc = np.empty(capacity, dtype=np.int32)
    goal_row = goal // cols
    goal_col = goal - goal_row * cols
    offsets = np.empty(8, dtype=np.int64)
    steps = np.empty(8)
    for move in range(8):
        offsets[move] = MOVES[move, 0] * cols + MOVES[move, 1]
        steps[move] = 1.0 if move < 4 else diagonal_step
    use_field = heuristic == H_FIELD
    node[start, 1] = 0.0
    parent[start] = -1
    if use_field:
        start_h = h_scale * h_field[start]
    else:
        start_h = h_scale * _h(start // cols, start % cols, goal_row, goal_col, heuristic, diagonal_step)
    hf[0] = start_h
    hg[0] = 0.0
    hc[0] = start
    size = 1
    expanded = 0
    while size > 0:
        index = hc[0]
        here_g = hg[0]
        size = _pop(hf, hg, hc, size)
        if here_g != node[index, 1]:
            continue  # stale: the cell was reached cheaper since, or is closed (its g is stored negated)
        node[index, 1] = -here_g
        expanded += 1
        if index == goal:
            return parent, here_g, expanded
        if size + 8 > capacity:
            capacity *= 2
            hf, hg, hc = _grown_heap(hf, hg, hc, size, capacity)
        row = index // cols
        col = index - row * cols
        here_cost = node[index, 0]
        inside = 0 < row < rows - 1 and 0 < col < cols - 1
        for move in range(8):
            if not inside:
                n_row = row + MOVES[move, 0]
                n_col = col + MOVES[move, 1]
                if n_row < 0 or n_row >= rows or n_col < 0 or n_col >= cols:
                    continue
            n_index = index + offsets[move]
            n_cost = node[n_index, 0]
            if n_cost == np.inf:
                continue
            # No corner cutting: the two orthogonal cells beside a diagonal move must be finite.
            if (
                move >= 4
                and no_corner_cutting
                and (
                    node[index + MOVES[move, 1], 0] == np.inf
                    or node[index + MOVES[move, 0] * cols, 0] == np.inf
                )
            ):
                continue
            if model == MODEL_MEAN:
                edge = steps[move] * 0.5 * (here_cost + n_cost)
                if use_factors:
                    edge *= factors[move, index]
            else:
                edge = steps[move] * n_cost
            tentative = here_g + edge
            if tentative < node[n_index, 1]:
                node[n_index, 1] = tentative
                parent[n_index] = index
                if use_field:
                    n_h = h_scale * h_field[n_index]
                else:
                    n_h = h_scale * _h(
                        row + MOVES[move, 0],
                        col + MOVES[move, 1],
                        goal_row,
                        goal_col,
                        heuristic,
                        diagonal_step,
                    )
                _sift_up(hf, hg, hc, size, tentative + n_h, tentative, n_index)
                size += 1
    return parent, np.inf, expanded
