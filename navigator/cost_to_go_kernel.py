"""The compiled cost-to-go field: Dijkstra *backwards* from the goal over the planner's edge model.

``field[a]`` is the cheapest cost of a path from cell ``a`` to the goal (``inf`` when none), over exactly
the edges ``navigator.astar_kernel.search`` uses with ``MODEL_MEAN``::

    edge(a -> b) = step(m) * (cost[a] + cost[b]) / 2 * factor[m, a]

so a backward step from ``b`` relaxes each predecessor ``a = b - MOVES[m]`` with the factor of ``a``
(direction factors are not symmetric). The field is what ``navigator.replanning`` reuses: on a map
whose costs have since only *risen*, the old field is still a lower bound of the cost to go and it is
consistent, so A* with it as the heuristic stays optimal while expanding little more than the new path.
"""

from __future__ import annotations

import numba
import numpy as np

from navigator.astar_kernel import MOVES, _pop, _sift_up


# nogil: in real time the search runs on the planner thread (navigator.plan_worker) and the control
# thread must keep ticking meanwhile.
@numba.njit(cache=True, error_model="numpy", nogil=True)
def cost_to_go(
    cost: np.ndarray,
    cols: int,
    goal: int,
    factors: np.ndarray,
    use_factors: bool,
    diagonal_step: float,
) -> np.ndarray:
    """``(cells,)`` cheapest cost from every cell to ``goal`` (flat row-major grid ``cols`` wide).

    No corner cutting: a diagonal move needs both orthogonal cells beside it finite.
    """
    n = cost.size
    rows = n // cols
    field = np.full(n, np.inf)
    closed = np.zeros(n, dtype=np.uint8)
    capacity = max(1024, n // 8)
    hf = np.empty(capacity)
    hg = np.empty(capacity)
    hc = np.empty(capacity, dtype=np.int32)
    field[goal] = 0.0
    hf[0] = 0.0
    hg[0] = 0.0
    hc[0] = goal
    size = 1
    while size > 0:
        index = hc[0]
        size = _pop(hf, hg, hc, size)
        if closed[index]:
            continue  # a stale entry
        closed[index] = 1
        if size + 8 > capacity:
            capacity *= 2
            grown_f = np.empty(capacity)
            grown_f[:size] = hf[:size]
            grown_g = np.empty(capacity)
            grown_g[:size] = hg[:size]
            grown_c = np.empty(capacity, dtype=np.int32)
            grown_c[:size] = hc[:size]
            hf, hg, hc = grown_f, grown_g, grown_c
        row = index // cols
        col = index - row * cols
        here_cost = cost[index]
        here = field[index]
        for move in range(8):
            d_row = MOVES[move, 0]
            d_col = MOVES[move, 1]
            # The predecessor that reaches this cell by ``move``.
            p_row = row - d_row
            p_col = col - d_col
            if p_row < 0 or p_row >= rows or p_col < 0 or p_col >= cols:
                continue
            p_index = p_row * cols + p_col
            if closed[p_index]:
                continue
            p_cost = cost[p_index]
            if p_cost == np.inf:
                continue
            step = 1.0
            if move >= 4:
                # The diagonal move p -> here passes the cells (p_row, col) and (row, p_col).
                if cost[p_row * cols + col] == np.inf or cost[row * cols + p_col] == np.inf:
                    continue
                step = diagonal_step
            edge = step * 0.5 * (p_cost + here_cost)
            if use_factors:
                edge *= factors[move, p_index]
            tentative = here + edge
            if tentative < field[p_index]:
                field[p_index] = tentative
                # Dijkstra: the key is the cost itself (no heuristic); the "g" tie-break key is the same.
                _sift_up(hf, hg, hc, size, tentative, tentative, p_index)
                size += 1
    return field
