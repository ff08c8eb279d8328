import itertools
import math
import time

import numpy as np
import pytest
from scipy.sparse import lil_matrix
from scipy.sparse.csgraph import dijkstra

from navigator import astar_bucket_kernel, astar_kernel
from navigator.astar import HEURISTICS, SQRT2, astar
from navigator.errors import NoPathError, PlanningError

MAZE = [[1, 1, 1, 1, 1, 1], [1, 2, 2, 1, 1, 1], [1, 2, 1, 1, 1, 1], [1, 2, 1, 2, 2, 1], [1, 1, 1, 2, 1, 1]]


def maze_cost():
    maze = np.array(MAZE)
    return np.where(maze == 1, np.inf, 1.0)


def path_cost(cost, cells):
    total = 0.0
    for (r0, c0), (r1, c1) in itertools.pairwise(cells):
        assert max(abs(r1 - r0), abs(c1 - c0)) == 1
        total += math.hypot(r1 - r0, c1 - c0) * 0.5 * (cost[r0, c0] + cost[r1, c1])
    return total


def dijkstra_cost(cost, start, goal):
    """An independent reference: scipy's Dijkstra over the same 8-connected, no-corner-cutting edges."""
    rows, cols = cost.shape
    graph = lil_matrix((rows * cols, rows * cols))
    for r in range(rows):
        for c in range(cols):
            if not np.isfinite(cost[r, c]):
                continue
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    nr, nc = r + dr, c + dc
                    if (dr, dc) == (0, 0) or not (0 <= nr < rows and 0 <= nc < cols):
                        continue
                    if not np.isfinite(cost[nr, nc]):
                        continue
                    if dr and dc and not (np.isfinite(cost[r, nc]) and np.isfinite(cost[nr, c])):
                        continue
                    graph[r * cols + c, nr * cols + nc] = (
                        math.hypot(dr, dc) * 0.5 * (cost[r, c] + cost[nr, nc])
                    )
    distances = dijkstra(graph.tocsr(), directed=True, indices=start[0] * cols + start[1])
    return distances[goal[0] * cols + goal[1]]


@pytest.mark.parametrize("heuristic", HEURISTICS)
def test_maze_shortest_paths(heuristic):
    cost = maze_cost()
    result = astar(cost, (1, 2), (3, 1), heuristic)
    assert result.cells == [(1, 2), (1, 1), (2, 1), (3, 1)]  # no cutting the (1,1)-(2,2) corner
    assert result.cost == pytest.approx(3.0)
    other = astar(cost, (3, 4), (4, 3), heuristic)
    assert other.cost == pytest.approx(2.0)
    with pytest.raises(NoPathError, match=r"\(1, 1\).*\(4, 3\)"):
        astar(cost, (1, 1), (4, 3), heuristic)


# Every search over every heuristic it supports: the heap takes all three, the bucket search only octile.
SEARCH_CASES = [("heap", h) for h in HEURISTICS] + [("bucket", "octile"), ("auto", "octile")]


@pytest.mark.parametrize(("search", "heuristic"), SEARCH_CASES)
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_matches_dijkstra_on_random_grids(search, heuristic, seed):
    rng = np.random.default_rng(seed)
    cost = 1.0 + 4.0 * rng.random((18, 23))
    cost[rng.random(cost.shape) < 0.25] = np.inf
    finite = np.argwhere(np.isfinite(cost))
    for _ in range(5):
        start = tuple(int(v) for v in finite[rng.integers(len(finite))])
        goal = tuple(int(v) for v in finite[rng.integers(len(finite))])
        reference = dijkstra_cost(cost, start, goal)
        if np.isinf(reference):
            with pytest.raises(NoPathError):
                astar(cost, start, goal, heuristic, search=search)
            continue
        result = astar(cost, start, goal, heuristic, search=search)
        assert result.cost == pytest.approx(reference, rel=1e-12)
        assert result.cells[0] == start and result.cells[-1] == goal
        assert path_cost(cost, result.cells) == pytest.approx(result.cost, rel=1e-12)
        assert all(np.isfinite(cost[cell]) for cell in result.cells)


def test_weighted_astar_is_bounded_and_expands_less():
    rng = np.random.default_rng(5)
    cost = 1.0 + rng.random((60, 60))
    optimal = astar(cost, (0, 0), (59, 45))
    greedy = astar(cost, (0, 0), (59, 45), weight=2.0)
    assert optimal.cost <= greedy.cost <= 2.0 * optimal.cost
    assert greedy.expanded < optimal.expanded


def test_bad_requests():
    cost = maze_cost()
    with pytest.raises(PlanningError, match="outside"):
        astar(cost, (1, 1), (9, 9))
    with pytest.raises(PlanningError, match="lethal"):
        astar(cost, (0, 0), (1, 1))
    with pytest.raises(PlanningError, match="heuristic"):
        astar(cost, (1, 1), (3, 1), "chebyshev")
    with pytest.raises(PlanningError, match="NaN"):
        astar(np.full((3, 3), np.nan), (0, 0), (1, 1))


def test_same_cell_and_determinism():
    cost = np.ones((5, 5))
    assert astar(cost, (2, 2), (2, 2)).cells == [(2, 2)]
    assert astar(cost, (0, 0), (4, 2)) == astar(cost, (0, 0), (4, 2))


def test_large_grid_is_quick():
    rng = np.random.default_rng(11)
    cost = 1.0 + 3.0 * rng.random((200, 200))
    cost[rng.random(cost.shape) < 0.2] = np.inf
    cost[0, 0] = cost[199, 199] = 1.0
    # Compiled (or loaded from numba's cache) first: the bound is the search's, not a cold compile's (a
    # worker of the parallel suite can meet this test before any other A* test).
    astar(np.ones((4, 4)), (0, 0), (3, 3))
    started = time.perf_counter()
    result = astar(cost, (0, 0), (199, 199))
    assert time.perf_counter() - started < 1.0
    assert result.cells[-1] == (199, 199)


@pytest.mark.parametrize("spread", [10.0, 1000.0])
def test_bucket_search_matches_dijkstra_on_integer_costs_and_wide_spreads(spread):
    # Integer costs as in the benchmark (many exact ties), and a spread of 1000 that needs thousands of
    # buckets in the ring (a key jumps far ahead of the bucket being emptied).
    rng = np.random.default_rng(int(spread))
    cost = rng.integers(1, int(spread) + 1, size=(30, 27)).astype(np.float64)
    cost[rng.random(cost.shape) < 0.2] = np.inf
    cost[0, 0] = cost[29, 26] = 1.0
    for start, goal in [((0, 0), (29, 26)), ((29, 26), (0, 0))]:
        reference = dijkstra_cost(cost, start, goal)
        if np.isinf(reference):
            with pytest.raises(NoPathError):
                astar(cost, start, goal, search="bucket")
            continue
        bucket = astar(cost, start, goal, search="bucket")
        heap = astar(cost, start, goal, search="heap")
        assert bucket.cost == pytest.approx(reference, rel=1e-12)
        assert heap.cost == pytest.approx(reference, rel=1e-12)
        assert path_cost(cost, bucket.cells) == pytest.approx(bucket.cost, rel=1e-12)


def test_bucket_kernel_solves_the_entered_cell_model_like_the_heap_kernel():
    # MODEL_TARGET (pyastar2d's problem: cost of the entered cell, diagonal step 1, corners may be cut).
    rng = np.random.default_rng(9)
    cost = rng.integers(1, 11, size=(40, 50)).astype(np.float64)
    cost[rng.random(cost.shape) < 0.2] = np.inf
    cost[0, 0] = cost[-1, -1] = 1.0
    flat = cost.ravel()
    frame, bad, c_min, c_max = astar_bucket_kernel.padded(flat, 50)
    assert (bad, c_min, c_max) == (0, 1.0, 10.0)
    slots = astar_bucket_kernel.slots_needed(c_max, c_min, 0.75, 1.0)
    _, bucket_cost, _ = astar_bucket_kernel.search(
        frame, 50, 0, flat.size - 1, 0.75, c_min, slots, np.ones((8, 1)), False,
        astar_kernel.MODEL_TARGET, 1.0, False,
    )  # fmt: skip
    _, heap_cost, _ = astar_kernel.search(
        flat, 50, 0, flat.size - 1, astar_kernel.H_OCTILE, 1.0, np.ones((8, 1)), False,
        astar_kernel.MODEL_TARGET, 1.0, False,
    )  # fmt: skip
    assert np.isfinite(heap_cost)
    assert bucket_cost == heap_cost  # integer sums: exact


def test_bucket_slots_cover_the_largest_reduced_edge():
    slots = astar_bucket_kernel.slots_needed(10 * SQRT2, 1.0, 0.75, SQRT2)
    assert slots & (slots - 1) == 0  # a power of two (a mask picks the slot)
    assert slots * 0.25 >= 10 * SQRT2 + 0.75 * SQRT2 + 0.25


def test_search_choice():
    cost = maze_cost()
    with pytest.raises(PlanningError, match="unknown search"):
        astar(cost, (1, 2), (3, 1), search="dijkstra")
    for kwargs in ({"heuristic": "euclidean"}, {"weight": 2.0}, {"field": np.zeros(cost.shape)}):
        with pytest.raises(PlanningError, match="bucket search needs"):
            astar(cost, (1, 2), (3, 1), search="bucket", **kwargs)
    with pytest.raises(PlanningError, match="NaN"):
        astar(np.full((3, 3), np.nan), (0, 0), (1, 1), search="bucket")
    # auto: a plateau goes to the heap (its tie-break walks straight), anything else to the buckets,
    # which expand more cells here (alpha < 1 on the heuristic) for the same optimal cost.
    rng = np.random.default_rng(2)
    varied = 1.0 + rng.random((40, 40))
    auto, heap, bucket = (astar(varied, (0, 0), (39, 30), search=s) for s in ("auto", "heap", "bucket"))
    assert auto == bucket
    assert bucket.cost == pytest.approx(heap.cost, rel=1e-12)
    flat = np.ones((40, 40))
    assert astar(flat, (0, 0), (39, 39)) == astar(flat, (0, 0), (39, 39), search="heap")
