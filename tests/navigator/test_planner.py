import math

import numpy as np
import pytest

from navigator.errors import NoPathError, PlanningError
from navigator.planner import Planner
from navigator.terrain import TerrainMap, disc_mask, from_maze
from navigator.vehicle import VehicleParams

MAZE = [[1, 1, 1, 1, 1, 1], [1, 2, 2, 1, 1, 1], [1, 2, 1, 1, 1, 1], [1, 2, 1, 2, 2, 1], [1, 1, 1, 2, 1, 1]]
PARAMS = VehicleParams()


def test_paper_maze_scaled_to_metres():
    terrain = from_maze(MAZE, 3.0, resolution_m=0.25)
    planner = Planner(terrain, PARAMS)
    path = planner.plan((7.5, 4.5), (4.5, 10.5))  # maze cell (1, 2) to (3, 1)
    np.testing.assert_array_equal(path.points[0], [7.5, 4.5])
    np.testing.assert_array_equal(path.points[-1], [4.5, 10.5])
    assert 8.0 < path.length_m < 9.2  # west 3 m then north 6 m, a little shorter round the corner
    for x, y in path.points:
        assert not terrain.obstacles[terrain.cell_of(x, y)]
    # A plan does not change once made: the follower relies on it to know the path again by identity.
    assert not path.points.flags.writeable and path.points.base is None
    with pytest.raises(NoPathError):
        planner.plan((7.5, 4.5), (10.5, 10.5))  # the other open region
    with pytest.raises(PlanningError, match="not on the map"):
        planner.plan((7.5, 4.5), (100.0, 4.5))
    with pytest.raises(PlanningError, match="lethal"):
        planner.plan((1.0, 1.0), (4.5, 10.5))


def test_lethal_slope_cells_are_never_on_the_path():
    rows, cols, res = 40, 60, 0.25
    elevation = np.zeros((rows, cols))
    # A ridge across most of the map whose flanks (grade 1.2, 50 deg) are past firm ground's limits.
    ridge_cols = slice(28, 32)
    elevation[:, ridge_cols] = np.array([0.3, 0.6, 0.6, 0.3])[np.newaxis, :]
    elevation[:8, ridge_cols] = 0.0  # a gap at the south end
    terrain = TerrainMap(elevation, np.zeros((rows, cols), np.uint8), np.zeros((rows, cols), bool), res)
    planner = Planner(terrain, PARAMS)
    path = planner.plan((2.0, 7.0), (13.0, 7.0))
    cost = planner.cost_grid
    assert np.isinf(cost).any()
    for x, y in path.points:
        assert np.isfinite(cost[terrain.cell_of(x, y)])
    assert min(y for _, y in path.points) < 2.0  # it went round through the gap
    assert path.length_m > 11.0


def test_update_obstacles_reroutes():
    terrain = TerrainMap(np.zeros((40, 40)), np.zeros((40, 40), np.uint8), np.zeros((40, 40), bool), 0.25)
    planner = Planner(terrain, PARAMS)
    straight = planner.plan((2.0, 5.0), (8.0, 5.0))
    assert straight.length_m == pytest.approx(6.0, abs=0.2)
    planner.update_obstacles(disc_mask(terrain, 5.0, 5.0, 1.0))
    detour = planner.plan((2.0, 5.0), (8.0, 5.0))
    assert detour.length_m > straight.length_m + 0.5
    assert min(math.hypot(x - 5.0, y - 5.0) for x, y in detour.points) > 1.0 + PARAMS.footprint_radius_m - 0.2


def test_unknown_heuristic():
    terrain = from_maze(MAZE, 3.0)
    with pytest.raises(PlanningError, match="heuristic"):
        Planner(terrain, PARAMS, heuristic="dijkstra")
