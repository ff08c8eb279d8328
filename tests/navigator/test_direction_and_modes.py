"""Direction-dependent costs, cost modes, lethal slopes, and optimality with direction factors."""

import math

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from navigator.astar import HEURISTICS, astar
from navigator.astar_kernel import MOVES
from navigator.direction_costs import direction_factors
from navigator.errors import PlanningError
from navigator.planner import Planner
from navigator.terrain import TerrainMap, procedural
from navigator.vehicle import VehicleParams

PARAMS = VehicleParams()


def _dijkstra_cost(
    cost: np.ndarray, factors: np.ndarray, start: tuple[int, int], goal: tuple[int, int]
) -> float:
    """Independent solver: the documented edge model as a sparse graph, scipy's Dijkstra."""
    rows, cols = cost.shape
    src, dst, weight = [], [], []
    for move, (dr, dc) in enumerate(MOVES.tolist()):
        step = math.sqrt(2.0) if dr and dc else 1.0
        for r in range(rows):
            for c in range(cols):
                nr, nc = r + dr, c + dc
                if not (0 <= nr < rows and 0 <= nc < cols):
                    continue
                if not (np.isfinite(cost[r, c]) and np.isfinite(cost[nr, nc])):
                    continue
                if dr and dc and not (np.isfinite(cost[r, nc]) and np.isfinite(cost[nr, c])):
                    continue
                edge = step * 0.5 * (cost[r, c] + cost[nr, nc]) * factors[move, r, c]
                if np.isfinite(edge):
                    src.append(r * cols + c)
                    dst.append(nr * cols + nc)
                    weight.append(edge)
    graph = coo_matrix((weight, (src, dst)), shape=(rows * cols, rows * cols)).tocsr()
    return float(dijkstra(graph, indices=start[0] * cols + start[1])[goal[0] * cols + goal[1]])


@pytest.mark.parametrize(("search", "heuristic"), [("heap", h) for h in HEURISTICS] + [("bucket", "octile")])
@pytest.mark.parametrize("seed", [3, 4, 5])
def test_terrain_mode_is_optimal_against_dijkstra(search: str, heuristic: str, seed: int) -> None:
    terrain = procedural((24, 30), 0.25, np.random.default_rng(seed), hill_height_m=1.5, hill_count=5,
                         class_patch_count=3, hill_radius_m=(0.8, 2.0))  # fmt: skip
    planner = Planner(terrain, PARAMS, heuristic=heuristic, inflation_m=0.0)
    cost = np.asarray(planner.cost_grid)
    factors = np.asarray(planner.direction_factors)
    assert np.isinf(factors).any() and (factors[np.isfinite(factors)] >= 1.0).all()
    free = np.argwhere(np.isfinite(cost))
    rng = np.random.default_rng(seed)
    for _ in range(3):
        a, b = rng.choice(len(free), 2, replace=False)
        start = (int(free[a][0]), int(free[a][1]))
        goal = (int(free[b][0]), int(free[b][1]))
        expected = _dijkstra_cost(cost, factors, start, goal)
        if not np.isfinite(expected):
            continue
        result = astar(cost, start, goal, heuristic, factors=factors, search=search)
        assert result.cost == pytest.approx(expected, rel=1e-9)


def _hill(rows: int = 60, cols: int = 60, res: float = 0.25, height: float = 1.6) -> TerrainMap:
    ys, xs = np.mgrid[0:rows, 0:cols] * res
    centre = (cols * res / 2, rows * res / 2)
    elevation = height * np.exp(-((xs - centre[0]) ** 2 + (ys - centre[1]) ** 2) / (2 * 2.5**2))
    return TerrainMap(elevation, np.zeros((rows, cols), np.uint8), np.zeros((rows, cols), bool), res)


def test_side_slopes_cost_more_than_climbing_the_same_slope() -> None:
    terrain = _hill()
    factors = direction_factors(terrain, PARAMS)
    # West of the hill's centre the ground rises to the east: moving east climbs, moving north crosses.
    row, col = 30, 20
    east, west, south = 3, 2, 0
    assert tuple(MOVES[east]) == (0, 1) and tuple(MOVES[west]) == (0, -1) and tuple(MOVES[south]) == (-1, 0)
    cross = factors[south, row, col]
    climb = factors[east, row, col]
    descend = factors[west, row, col]
    assert cross > climb > descend >= 1.0


def test_steep_side_slope_is_forbidden_but_climbing_it_is_not() -> None:
    # A 34 deg plane: firm ground climbs it (limit 38.7 - 3 deg margin), but a narrow rover (tip roll
    # 36.9 deg, 10 deg margin) must not cross it sideways.
    rows, cols, res = 10, 10, 0.25
    grade = math.tan(math.radians(34.0))
    elevation = np.tile(np.arange(cols) * res * grade, (rows, 1))  # rises to the east
    terrain = TerrainMap(elevation, np.zeros((rows, cols), np.uint8), np.zeros((rows, cols), bool), res)
    params = VehicleParams(track_m=0.45)  # tip roll atan(0.225 / 0.3) = 36.9 deg
    factors = direction_factors(terrain, params)
    assert np.isfinite(factors[3, 5, 5])  # east: straight up 34 deg, under 35.7 deg
    assert np.isinf(factors[0, 5, 5])  # north: roll 34 deg > 36.9 - 10 deg


def test_classical_mode_ignores_slopes_and_drives_straight_across() -> None:
    terrain = _hill(height=3.0)
    start, goal = (1.0, 5.5), (14.0, 9.5)
    terrain_path = Planner(terrain, PARAMS).plan(start, goal)
    classical = Planner(terrain, PARAMS, cost_mode="classical")
    classical_path = classical.plan(start, goal)
    assert np.isfinite(classical.cost_grid[4:-4, 4:-4]).all() and classical.direction_factors is None
    assert classical_path.length_m < terrain_path.length_m
    steep = Planner(terrain, PARAMS)
    lethal = ~np.isfinite(steep.cost_grid)
    assert lethal.any()
    for x, y in terrain_path.points:
        assert not lethal[terrain.cell_of(x, y)]
    with pytest.raises(PlanningError, match="cost mode"):
        Planner(terrain, PARAMS, cost_mode="fancy")


def test_a_hill_is_taken_diagonally_not_sideways() -> None:
    # A long east-rising ramp between start (south-west) and goal (north-west + up): crossing the ramp
    # sideways (north) is dearer than going down it at an angle and back up, so the path is not a
    # straight north line along the flank.
    rows, cols, res = 40, 40, 0.25
    grade = math.tan(math.radians(20.0))
    elevation = np.tile(np.clip(np.arange(cols) - 20, 0, None) * res * grade, (rows, 1))  # flat west of 5 m
    terrain = TerrainMap(elevation, np.zeros((rows, cols), np.uint8), np.zeros((rows, cols), bool), res)
    planner = Planner(terrain, PARAMS, inflation_m=0.0)
    path = planner.plan((6.6, 1.5), (6.6, 8.5))  # both on the flank, due north of each other
    flat = Planner(terrain, PARAMS, cost_mode="classical", inflation_m=0.0).plan((6.6, 1.5), (6.6, 8.5))
    assert np.ptp(flat.points[:, 0]) < 0.3  # the classical path goes straight along the flank
    assert path.points[:, 0].min() < 5.0  # the terrain path leaves the flank for the flat ground west
