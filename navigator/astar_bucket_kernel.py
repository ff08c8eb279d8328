"""Exact A* with a bucket queue (numba): the default search for the octile heuristic at weight 1.

Why buckets are exact here. A* with a consistent heuristic ``h`` is Dijkstra on the reduced edge costs
``edge(a, b) - h(a) + h(b)``. Every move costs at least ``step * c_min`` (``c_min`` the cheapest finite
cell cost; direction factors are >= 1) and the octile distance changes by at most ``step`` per move, so
with ``h = alpha * c_min * octile`` (``0 <= alpha < 1``) every reduced cost is at least
``span = (1 - alpha) * c_min``. Keys ``f = g + h`` are dropped into buckets ``floor(f / span)``; when the
lowest non-empty bucket ``i`` is scanned, every other open cell has ``f >= i * span`` and any path through
it to a cell ``u`` of bucket ``i`` costs ``>= (i + 1) * span > f(u)``: each cell of the lowest bucket is
already final, in whatever order the bucket is emptied. So the search returns an optimal path, like the
heap search, but a push and a pop are O(1) (an append and a pop at the end of an array) instead of a
heap's O(log n) sift with comparisons across scattered memory.

The price is the factor ``alpha`` on the heuristic: cells with ``g + alpha * h < C*`` are expanded instead
of ``g + h < C*``. On maps where the octile bound is loose (costs that vary a lot, obstacles), A* expands
nearly every cell anyway and the factor costs nothing; on near-uniform maps it expands more than the heap
search, and on a plateau far more (``navigator.astar`` then takes the heap; docs/planning.md has numbers).

Layout: the grid is copied into a frame one cell wider on every side, filled with ``inf``, so the
neighbour loop has no bounds checks; cells are indices into that padded grid. A closed cell holds ``-g``
(``tentative < g`` then fails without a separate closed array). Buckets are a ring of ``slots`` arrays:
a key never jumps more than the largest reduced edge ahead of the bucket being scanned.

Edge models as in ``navigator.astar_kernel``: ``MODEL_MEAN`` (the planner's, ``step * (cost[a] + cost[b])
/ 2 * factor[move, a]``) and ``MODEL_TARGET`` (``step * cost[b]``, pyastar2d's and libtcod's).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numpy as np

from navigator import astar_kernel
from navigator.astar_kernel import MODEL_MEAN, MOVES
from navigator.kernel_cache import sources_fingerprint

#: The ring would need more slots than this (a huge spread between the cheapest and dearest edge): the
#: caller should use the heap search instead.
MAX_SLOTS = 1 << 16


def slots_needed(max_edge: float, c_min: float, alpha: float, diagonal_step: float) -> int:
    """Ring size: the largest reduced edge (``max_edge`` plus the heuristic's change) over a bucket's span."""
    span = (1.0 - alpha) * c_min
    needed = math.ceil((max_edge + alpha * c_min * diagonal_step) / span) + 2
    # A power of two, so the slot of a bucket is a mask, not an integer division.
    return 1 << (needed - 1).bit_length()


@numba.njit(cache=True, inline="always")
def _octile(row: int, col: int, goal_row: int, goal_col: int, diagonal_step: float) -> float:
    d_row = abs(row - goal_row)
    d_col = abs(col - goal_col)
    if d_row > d_col:
        return d_row + (diagonal_step - 1.0) * d_col
    return d_col + (diagonal_step - 1.0) * d_row


@numba.njit(cache=True, error_model="numpy")
def padded(cost: np.ndarray, cols: int) -> tuple[np.ndarray, int, float, float]:
    """``cost`` (flat, row-major) inside a one-cell ``inf`` frame, ``(rows + 2) * (cols + 2)`` cells, and in
    the same pass: (the frame, cells that are NaN or <= 0, cheapest finite cost, dearest finite cost).
    """
    rows = cost.size // cols
    stride = cols + 2
    n = (rows + 2) * stride
    frame = np.empty(n)
    for i in range(stride):
        frame[i] = np.inf
        frame[n - stride + i] = np.inf
    bad = 0
    low = np.inf
    high = 0.0
    for r in range(rows):
        base = (r + 1) * stride
        frame[base] = np.inf
        frame[base + stride - 1] = np.inf
        for c in range(cols):
            value = cost[r * cols + c]
            frame[base + 1 + c] = value
            if not value > 0.0:  # also true for NaN
                bad += 1
            elif value != np.inf:
                low = min(low, value)
                high = max(high, value)
    return frame, bad, low, high


@numba.njit(cache=True, error_model="numpy")
def _grown(buckets: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    slots, capacity = buckets.shape
    grown = np.empty((slots, 2 * capacity), dtype=np.int32)
    for slot in range(slots):
        # A loop, not a slice assignment: that compiles numba's shape-mismatch message (seconds of a cold
        # start) for a copy whose shapes cannot differ.
        for k in range(lengths[slot]):
            grown[slot, k] = buckets[slot, k]
    return grown


def _compile_search(fingerprint: str) -> Callable[..., tuple[np.ndarray, float, int]]:
    """``search``, with ``fingerprint`` (of ``navigator.astar_kernel``, whose moves and edge models it
    compiles in) in numba's cache key: see ``navigator.kernel_cache``."""

    # nogil: in real time the search runs on the planner thread (navigator.plan_worker); the control
    # thread must keep ticking meanwhile.
    @numba.njit(cache=True, error_model="numpy", nogil=True)
    def search(
        frame: np.ndarray,
        cols: int,
        start: int,
        goal: int,
        alpha: float,
        c_min: float,
        slots: int,
        factors: np.ndarray,
        use_factors: bool,
        model: int,
        diagonal_step: float,
        no_corner_cutting: bool,
    ) -> tuple[np.ndarray, float, int]:
        """Bucket A* over ``frame`` (``padded``'s grid of a map ``cols`` wide). Returns (parent, goal cost,
        expanded).

        ``start`` and ``goal`` are flat indices of the *unpadded* map; ``parent`` is over the padded grid
        (indices of the padded grid, -1 at the start; ``navigator.astar.trace`` maps it back). ``slots`` from
        ``slots_needed``; ``factors`` (indexed by unpadded cell) as for ``navigator.astar_kernel.search``.
        The goal cost is ``inf`` when the goal is unreachable.
        """
        _ = fingerprint  # in the closure, so in numba's cache key (see _compile_search)
        stride = cols + 2
        # row = index // stride through a float reciprocal: exact for any grid that fits in memory (the
        # fraction col / stride stays >= 0.5 / stride away from an integer) and far cheaper than a division.
        inv_stride = 1.0 / stride
        g = np.full(frame.size, np.inf)
        parent = np.empty(frame.size, dtype=np.int32)
        inv_span = 1.0 / ((1.0 - alpha) * c_min)
        h_scale = alpha * c_min
        buckets = np.empty((slots, 256), dtype=np.int32)
        lengths = np.zeros(slots, dtype=np.int64)
        mask = slots - 1  # slots is a power of two
        goal_row = goal // cols + 1
        goal_col = goal % cols + 1
        source = (start // cols + 1) * stride + start % cols + 1
        target = goal_row * stride + goal_col
        g[source] = 0.0
        parent[source] = -1
        start_h = h_scale * _octile(source // stride, source % stride, goal_row, goal_col, diagonal_step)
        bucket = int(start_h * inv_span)
        buckets[bucket & mask, 0] = source
        lengths[bucket & mask] = 1
        longest = 1
        pending = 1
        expanded = 0
        while pending > 0:
            slot = bucket & mask
            while lengths[slot] > 0:
                lengths[slot] -= 1
                pending -= 1
                index = buckets[slot, lengths[slot]]
                here_g = g[index]
                if here_g < 0.0:
                    continue  # a duplicate entry of a cell already closed
                g[index] = -here_g
                expanded += 1
                if index == target:
                    return parent, here_g, expanded
                if longest + 8 > buckets.shape[1]:
                    buckets = _grown(buckets, lengths)
                row = int((index + 0.5) * inv_stride)
                col = index - row * stride
                here_cost = frame[index]
                # A diagonal move needs the two orthogonal cells beside it finite (no corner cutting).
                free_up = frame[index - stride] != np.inf
                free_down = frame[index + stride] != np.inf
                free_left = frame[index - 1] != np.inf
                free_right = frame[index + 1] != np.inf
                for move in range(8):
                    d_row = MOVES[move, 0]
                    d_col = MOVES[move, 1]
                    n_index = index + d_row * stride + d_col
                    # An obstacle (or a corner cut past one) makes the edge inf, so "tentative < g" fails:
                    # a select instead of two hard-to-predict branches (measured ~5-10 % faster).
                    n_cost = frame[n_index]
                    step = 1.0
                    if move >= 4:
                        step = diagonal_step
                        if no_corner_cutting:
                            vertical_free = free_up if d_row < 0 else free_down
                            horizontal_free = free_left if d_col < 0 else free_right
                            n_cost = n_cost if (vertical_free and horizontal_free) else np.inf
                    if model == MODEL_MEAN:
                        edge = step * 0.5 * (here_cost + n_cost)
                        if use_factors:
                            edge *= factors[move, (row - 1) * cols + col - 1]
                    else:
                        edge = step * n_cost
                    tentative = here_g + edge
                    if tentative < g[n_index]:
                        g[n_index] = tentative
                        parent[n_index] = index
                        n_h = h_scale * _octile(row + d_row, col + d_col, goal_row, goal_col, diagonal_step)
                        # >= bucket + 1 in exact arithmetic; rounding may land it in this bucket: still final
                        # to float tolerance, and the inner loop picks it up.
                        n_slot = max(int((tentative + n_h) * inv_span), bucket) & mask
                        buckets[n_slot, lengths[n_slot]] = n_index
                        lengths[n_slot] += 1
                        longest = max(longest, lengths[n_slot])
                        pending += 1
            bucket += 1
        return parent, np.inf, expanded

    return search


search = _compile_search(sources_fingerprint(astar_kernel))
