"""The compiled plan repair (numba): A* guided by a cost-to-go field, in time proportional to its work.

``navigator.replanning`` repairs a plan after a local change with the goal's cost-to-go field as the
heuristic; A* then expands little beyond the detour (thousands of cells on a map of millions). What is
left to pay is the per-plan O(cells) set-up of a fresh search: filling ``g`` with ``inf``, allocating
the parents. Here those arrays live as long as the field, and a *stamp* per cell says which plan wrote
its ``g`` and parent: a cell whose stamp is not the current plan's counts as unreached. Starting a plan
is then one increment, and a repair costs what it expands.

The search itself is ``navigator.astar_kernel.search`` with ``H_FIELD`` and ``MODEL_MEAN`` (same heap,
same tie-break, same edges), over the unpadded grid with bounds checks at the border.
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np

from navigator import astar_kernel
from navigator.astar_kernel import MOVES, _grown_heap, _pop, _sift_up
from navigator.kernel_cache import sources_fingerprint


@numba.njit(cache=True, error_model="numpy")
def costs_rose_only(new: np.ndarray, old: np.ndarray) -> tuple[int, bool]:
    """One pass over two flat grids: (cells of ``new`` NaN or <= 0, no cell of ``new`` below ``old``)."""
    bad = 0
    rose_only = True
    for i in range(new.size):
        value = new[i]
        if not value > 0.0:  # also true for NaN
            bad += 1
        elif value < old[i]:
            rose_only = False
    return bad, rose_only


def _compile_search(fingerprint: str) -> Callable[..., tuple[float, int]]:
    """``search``, with ``fingerprint`` (of ``navigator.astar_kernel``, whose heap it uses) in numba's cache
    key: see ``navigator.kernel_cache``."""

    # nogil: in real time the search runs on the planner thread (navigator.plan_worker); the control
    # thread must keep ticking meanwhile.
    @numba.njit(cache=True, error_model="numpy", nogil=True)
    def search(
        cost: np.ndarray,
        cols: int,
        start: int,
        goal: int,
        field: np.ndarray,
        h_scale: float,
        factors: np.ndarray,
        use_factors: bool,
        diagonal_step: float,
        g: np.ndarray,
        parent: np.ndarray,
        stamp: np.ndarray,
        plan_id: int,
    ) -> tuple[float, int]:
        """A* from ``start`` to ``goal`` (flat indices, row-major grid ``cols`` wide) with ``h_scale * field``
        as the heuristic. Returns (goal cost, expanded); the goal cost is ``inf`` when it is unreachable.

        ``g`` (float), ``parent`` and ``stamp`` (int32) are ``(cells,)`` work arrays kept between plans;
        ``plan_id`` must differ from every stamp already in ``stamp`` (the caller counts up). On return,
        ``parent`` holds the path for the cells stamped ``plan_id``.
        """
        _ = fingerprint  # in the closure, so in numba's cache key (see _compile_search)
        n = cost.size
        rows = n // cols
        capacity = 1024
        hf = np.empty(capacity)
        hg = np.empty(capacity)
        hc = np.empty(capacity, dtype=np.int32)
        stamp[start] = plan_id
        g[start] = 0.0
        parent[start] = -1
        hf[0] = h_scale * field[start]
        hg[0] = 0.0
        hc[0] = start
        size = 1
        expanded = 0
        while size > 0:
            index = hc[0]
            here_g = hg[0]
            size = _pop(hf, hg, hc, size)
            if here_g != g[index]:
                continue  # stale: reached cheaper since, or closed (its g is stored negated)
            g[index] = -here_g
            expanded += 1
            if index == goal:
                return here_g, expanded
            if size + 8 > capacity:
                capacity *= 2
                hf, hg, hc = _grown_heap(hf, hg, hc, size, capacity)
            row = index // cols
            col = index - row * cols
            here_cost = cost[index]
            for move in range(8):
                n_row = row + MOVES[move, 0]
                n_col = col + MOVES[move, 1]
                if n_row < 0 or n_row >= rows or n_col < 0 or n_col >= cols:
                    continue
                n_index = n_row * cols + n_col
                n_cost = cost[n_index]
                if n_cost == np.inf:
                    continue
                step = 1.0
                if move >= 4:
                    # No corner cutting: the two orthogonal cells beside a diagonal move must be finite.
                    if cost[row * cols + n_col] == np.inf or cost[n_row * cols + col] == np.inf:
                        continue
                    step = diagonal_step
                edge = step * 0.5 * (here_cost + n_cost)
                if use_factors:
                    edge *= factors[move, index]
                tentative = here_g + edge
                if stamp[n_index] != plan_id:
                    stamp[n_index] = plan_id
                    g[n_index] = np.inf
                if tentative < g[n_index]:
                    g[n_index] = tentative
                    parent[n_index] = index
                    n_h = h_scale * field[n_index]
                    _sift_up(hf, hg, hc, size, tentative + n_h, tentative, n_index)
                    size += 1
        return np.inf, expanded

    return search


search = _compile_search(sources_fingerprint(astar_kernel))
