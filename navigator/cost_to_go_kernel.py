"""The compiled cost-to-go field: Dijkstra *backwards* from the goal over the planner's edge model.

``field[a]`` is the cheapest cost of a path from cell ``a`` to the goal (``inf`` when none), over exactly
the edges ``navigator.astar_kernel.search`` uses with ``MODEL_MEAN``::

    edge(a -> b) = step(m) * (cost[a] + cost[b]) / 2 * factor[m, a]

so a backward step from ``b`` relaxes each predecessor ``a = b - MOVES[m]`` with the factor of ``a``
(direction factors are not symmetric). The field is what ``navigator.replanning`` reuses: on a map
whose costs have since only *risen*, the old field is still a lower bound of the cost to go and it is
consistent, so A* with it as the heuristic stays optimal while expanding little more than the new path.

Two versions, the same field: ``cost_to_go_buckets`` (the default) is Dijkstra with a bucket queue of
span ``c_min`` (every edge costs at least that, so each cell of the lowest bucket is final: the argument
of ``navigator.astar_bucket_kernel`` with no heuristic), over the padded grid; ``cost_to_go`` is the heap
version, kept for cost spreads so wide that the ring of buckets would be huge.
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np

from navigator import astar_bucket_kernel, astar_kernel
from navigator.astar_bucket_kernel import _grown
from navigator.astar_kernel import MOVES, _grown_heap, _pop, _sift_up
from navigator.kernel_cache import sources_fingerprint


def _compile_cost_to_go(fingerprint: str) -> Callable[..., np.ndarray]:
    """``cost_to_go``, with ``fingerprint`` (of ``navigator.astar_kernel``, whose heap it uses) in numba's
    cache key: see ``navigator.kernel_cache``."""

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
        _ = fingerprint  # in the closure, so in numba's cache key (see _compile_cost_to_go)
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
                hf, hg, hc = _grown_heap(hf, hg, hc, size, capacity)
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

    return cost_to_go


def _compile_cost_to_go_buckets(fingerprint: str) -> Callable[..., np.ndarray]:
    """``cost_to_go_buckets``, with ``fingerprint`` (of the A* kernels, whose heap and buckets it uses) in
    numba's cache key: see ``navigator.kernel_cache``."""

    # nogil: in real time the search runs on the planner thread (navigator.plan_worker); the control
    # thread must keep ticking meanwhile.
    @numba.njit(cache=True, error_model="numpy", nogil=True)
    def cost_to_go_buckets(
        frame: np.ndarray,
        cols: int,
        goal: int,
        c_min: float,
        slots: int,
        factors: np.ndarray,
        use_factors: bool,
        diagonal_step: float,
    ) -> np.ndarray:
        """``(cells,)`` cheapest cost from every cell to ``goal`` (a flat index of the unpadded map).

        ``frame``: ``astar_bucket_kernel.padded`` of the map (``cols`` wide); ``slots``:
        ``astar_bucket_kernel.slots_needed(max_edge, c_min, 0.0, diagonal_step)``. No corner cutting.
        """
        _ = fingerprint  # in the closure, so in numba's cache key (see _compile_cost_to_go_buckets)
        stride = cols + 2
        inv_stride = 1.0 / stride  # row = index // stride without a division (see the bucket kernel)
        rows = frame.size // stride - 2
        g = np.full(frame.size, np.inf)
        inv_span = 1.0 / c_min
        mask = slots - 1
        buckets = np.empty((slots, 256), dtype=np.int32)
        lengths = np.zeros(slots, dtype=np.int64)
        source = (goal // cols + 1) * stride + goal % cols + 1
        g[source] = 0.0
        buckets[0, 0] = source
        lengths[0] = 1
        longest = 1
        pending = 1
        bucket = 0
        while pending > 0:
            slot = bucket & mask
            while lengths[slot] > 0:
                lengths[slot] -= 1
                pending -= 1
                index = buckets[slot, lengths[slot]]
                here = g[index]
                if here < 0.0:
                    continue  # a duplicate entry of a settled cell
                g[index] = -here
                if longest + 8 > buckets.shape[1]:
                    buckets = _grown(buckets, lengths)
                row = int((index + 0.5) * inv_stride)
                col = index - row * stride
                here_cost = frame[index]
                for move in range(8):
                    d_row = MOVES[move, 0]
                    d_col = MOVES[move, 1]
                    # The predecessor that reaches this cell by ``move``.
                    p_index = index - d_row * stride - d_col
                    p_cost = frame[p_index]
                    step = 1.0
                    if move >= 4:
                        step = diagonal_step
                        # The diagonal move p -> here passes (p_row, col) and (row, p_col): inf if blocked.
                        if frame[index - d_row * stride] == np.inf or frame[index - d_col] == np.inf:
                            p_cost = np.inf
                    edge = step * 0.5 * (p_cost + here_cost)
                    if use_factors:
                        edge *= factors[move, (row - d_row - 1) * cols + col - d_col - 1]
                    tentative = here + edge
                    if tentative < g[p_index]:
                        g[p_index] = tentative
                        # >= bucket + 1 exactly; rounding may give this bucket (then this loop takes it).
                        p_slot = max(int(tentative * inv_span), bucket) & mask
                        buckets[p_slot, lengths[p_slot]] = p_index
                        lengths[p_slot] += 1
                        longest = max(longest, lengths[p_slot])
                        pending += 1
            bucket += 1
        field = np.empty(rows * cols)
        for r in range(rows):
            for c in range(cols):
                field[r * cols + c] = abs(g[(r + 1) * stride + c + 1])  # settled cells hold -cost
        return field

    return cost_to_go_buckets


cost_to_go = _compile_cost_to_go(sources_fingerprint(astar_kernel))
cost_to_go_buckets = _compile_cost_to_go_buckets(sources_fingerprint(astar_bucket_kernel, astar_kernel))
