import math

import numpy as np
import pytest

from navigator.costs import CostModel, inflate_obstacles, traversability_cost
from navigator.errors import ParameterError
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TERRAIN_CLASSES
from navigator.vehicle import VehicleParams

PARAMS = VehicleParams()


def terrain_with(elevation, classes=None, obstacles=None, res=0.5):
    shape = elevation.shape
    return TerrainMap(
        elevation,
        np.zeros(shape, np.uint8) if classes is None else classes,
        np.zeros(shape, bool) if obstacles is None else obstacles,
        res,
    )


def test_flat_cost_is_the_class_factor():
    classes = np.array([[0, 1, 2, 3, 4, 5]] * 6, dtype=np.uint8)
    cost = traversability_cost(terrain_with(np.zeros((6, 6)), classes), PARAMS, edge_is_obstacle=False)
    expected = [TERRAIN_CLASSES[c].cost_factor for c in range(6)]
    np.testing.assert_allclose(cost, np.array([expected] * 6))


def test_slope_raises_cost_and_steep_cells_are_lethal():
    res = 0.5
    xs = (np.arange(40) + 0.5) * res
    # Slope tan grows along x from 0 to 1.2.
    tan_slope = np.linspace(0.0, 1.2, 40)
    elevation = np.tile(np.cumsum(tan_slope) * res, (5, 1))
    cost = traversability_cost(
        terrain_with(elevation, res=res), PARAMS, edge_is_obstacle=False, roughness_weight=0
    )
    _, grad_x = np.gradient(elevation, res)  # (d/drow, d/dcol)
    slope = np.arctan(np.abs(grad_x))
    climb_limit = math.atan(0.8 - 0.02) - math.radians(3.0)
    tip_limit = PARAMS.tip_roll_rad - math.radians(10.0)  # the tighter one for this rover
    lethal = np.isinf(cost)
    np.testing.assert_array_equal(lethal, slope > min(climb_limit, tip_limit))
    assert lethal.any() and not lethal.all()
    finite = cost[2][~lethal[2]]
    assert np.all(np.diff(finite) >= 0.0) and finite[0] >= 1.0
    assert xs.size == 40


def test_sand_is_lethal_at_a_slope_firm_ground_climbs():
    tan = 0.3  # sand limit: atan(0.4 - 0.12) = 15.6 deg - 3 deg margin < 16.7 deg
    elevation = np.tile(np.arange(8) * 0.5 * tan, (8, 1))
    firm = traversability_cost(terrain_with(elevation), PARAMS, edge_is_obstacle=False)
    sandy = traversability_cost(
        terrain_with(elevation, np.full((8, 8), 2, np.uint8)), PARAMS, edge_is_obstacle=False
    )
    assert np.all(np.isfinite(firm)) and np.all(np.isinf(sandy))


def test_tip_limit_is_lethal_even_on_grippy_ground():
    steep = math.tan(PARAMS.tip_roll_rad - math.radians(5.0))  # climbable on firm? no; use a grippy class
    from navigator.terrain_classes import TerrainClass

    grippy = {0: TerrainClass(0, "velcro", 2.0, 0.0, 1.0, "test")}
    elevation = np.tile(np.arange(8) * 0.5 * steep, (8, 1))
    cost = traversability_cost(terrain_with(elevation), PARAMS, grippy, edge_is_obstacle=False)
    assert np.all(np.isinf(cost))
    relaxed = traversability_cost(
        terrain_with(elevation), PARAMS, grippy, edge_is_obstacle=False, tip_margin_rad=0
    )
    assert np.all(np.isfinite(relaxed))


def test_obstacle_inflation_uses_the_footprint():
    obstacles = np.zeros((21, 21), bool)
    obstacles[10, 10] = True
    terrain = terrain_with(np.zeros((21, 21)), obstacles=obstacles, res=0.1)
    clearance = PARAMS.footprint_radius_m + 0.1
    inflated = inflate_obstacles(terrain, clearance, edge_is_obstacle=False)
    rows, cols = np.indices((21, 21))
    # Distance from each centre to the obstacle square [1.0, 1.1] x [1.0, 1.1].
    gap_x = np.maximum(np.abs(cols - 10) - 0.5, 0.0) * 0.1
    gap_y = np.maximum(np.abs(rows - 10) - 0.5, 0.0) * 0.1
    np.testing.assert_array_equal(inflated, np.hypot(gap_x, gap_y) < clearance)
    cost = CostModel(inflation_m=0.1, edge_is_obstacle=False).grid(terrain, PARAMS)
    np.testing.assert_array_equal(np.isinf(cost), inflated)
    assert inflate_obstacles(terrain, 0.0, edge_is_obstacle=False)[10, 10]


def test_map_edge_is_lethal_by_default():
    cost = traversability_cost(terrain_with(np.zeros((20, 20)), res=0.25), PARAMS)
    assert np.all(np.isinf(cost[0])) and np.all(np.isinf(cost[:, -1]))
    assert np.isfinite(cost[10, 10])


def test_roughness_adds_cost_but_an_even_slope_is_not_rough():
    ramp = np.tile(np.arange(10) * 0.05, (10, 1))
    bumpy = ramp + np.where((np.indices((10, 10)).sum(axis=0) % 2) == 0, 0.03, -0.03)
    smooth_cost = traversability_cost(terrain_with(ramp), PARAMS, edge_is_obstacle=False, slope_weight=0.0)
    bumpy_cost = traversability_cost(terrain_with(bumpy), PARAMS, edge_is_obstacle=False, slope_weight=0.0)
    np.testing.assert_allclose(smooth_cost[2:-2, 2:-2], 1.0)
    assert np.all(bumpy_cost[2:-2, 2:-2] > 1.1)


def test_bad_weights_are_rejected():

    with pytest.raises(ParameterError, match="slope_weight"):
        CostModel(slope_weight=-1.0)


def test_grid_from_a_kept_ground_cost_is_the_grid_made_anew_and_refused_for_other_layers():
    rng = np.random.default_rng(5)
    terrain = terrain_with(rng.normal(0.0, 0.05, (30, 30)), rng.integers(0, 3, (30, 30)).astype(np.uint8))
    model = CostModel(inflation_m=0.2)
    ground = model.ground_cost(terrain, PARAMS)
    for rock in ((5, 5), (12, 20), (25, 8)):
        mask = np.zeros((30, 30), bool)
        mask[rock] = True
        terrain = terrain.with_obstacles(mask)
        kept = model.grid(terrain, PARAMS, ground=ground)
        np.testing.assert_array_equal(kept, model.grid(terrain, PARAMS))  # bit for bit, inf where lethal
        assert np.isinf(kept[rock])
    assert not ground.cost.flags.writeable and not ground.lethal.flags.writeable
    other = terrain_with(np.zeros((30, 30)))
    with pytest.raises(ParameterError, match="made for another terrain"):
        model.grid(other, PARAMS, ground=ground)
