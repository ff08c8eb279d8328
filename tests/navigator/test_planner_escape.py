"""A start inside an obstacle's clearance band plans out of it; a start inside an obstacle does not. A start
on a slope too steep for its class plans off it, to the nearest passable ground within reach."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navigator.errors import PlanningError
from navigator.planner import Planner
from navigator.terrain import TerrainMap
from navigator.terrain_classes import FIRM, MUDDY, SANDY
from navigator.vehicle import VehicleParams


def _flat_map_with_block() -> TerrainMap:
    obstacles = np.zeros((40, 40), dtype=bool)
    obstacles[18:22, 18:22] = True  # a 1 m block in the middle of a 10 m map
    return TerrainMap(
        elevation_m=np.zeros((40, 40)),
        terrain_class=np.zeros((40, 40), dtype=np.uint8),
        obstacles=obstacles,
        resolution_m=0.25,
    )


def test_start_in_clearance_band_escapes_to_nearest_free_cell():
    planner = Planner(_flat_map_with_block(), VehicleParams())
    start = (5.0, 4.25)  # just below the block, inside footprint + inflation
    assert not np.isfinite(planner.cost_grid[planner.terrain.cell_of(*start)])
    path = planner.plan(start, (5.0, 1.5))
    assert tuple(path.points[0]) == start
    second = planner.terrain.cell_of(*path.points[1])
    assert np.isfinite(planner.cost_grid[second])


def test_start_inside_obstacle_is_refused():
    planner = Planner(_flat_map_with_block(), VehicleParams())
    with pytest.raises(PlanningError, match="lethal"):
        planner.plan((5.0, 5.0), (5.0, 1.5))


def _hillside_with_sand(sand_x: tuple[float, float]) -> TerrainMap:
    """10 x 10 m rising north at 14 deg (past the table's sand, 12.6 deg with the margin; firm takes it),
    sandy for x in ``sand_x``, firm elsewhere."""
    ys, xs = (np.mgrid[0:40, 0:40] + 0.5) * 0.25
    classes = np.where((xs >= sand_x[0]) & (xs < sand_x[1]), SANDY, FIRM).astype(np.uint8)
    return TerrainMap(ys * math.tan(math.radians(14.0)), classes, np.zeros((40, 40), dtype=bool), 0.25)


def test_start_on_a_slope_too_steep_for_its_class_plans_off_it_to_the_nearest_passable_ground():
    # A rover that learned, on this slope, that its sand grips less stands on ground its beliefs forbid:
    # the nearest firm ground is 2.4 m away, past the clearance band's escape.
    planner = Planner(_hillside_with_sand((2.5, 7.5)), VehicleParams())
    start = (5.1, 5.0)
    assert not np.isfinite(planner.cost_grid[planner.terrain.cell_of(*start)])
    path = planner.plan(start, (9.0, 5.0))
    assert tuple(path.points[0]) == start
    assert path.points[1][0] >= 7.5  # off the sand, east, then on firm ground
    assert all(np.isfinite(planner.cost_grid[planner.terrain.cell_of(*p)]) for p in path.points[1:])
    assert path.checked_from_m == 0.0  # the way off is checked for the footprint from where it stands


def test_start_on_a_slope_with_no_passable_ground_within_reach_is_refused():
    planner = Planner(_hillside_with_sand((0.0, 10.0)), VehicleParams())
    with pytest.raises(PlanningError, match="lethal"):
        planner.plan((5.0, 5.0), (9.0, 5.0))


def test_the_way_off_a_slope_does_not_cross_another_class_too_steep_for_it():
    """A strip of mud (impassable at 14 deg) between the sand the rover stands on and the firm ground east:
    the nearest firm ground, across the mud, is no way off; the firm ground west, across sand only, is."""
    terrain = _hillside_with_sand((2.5, 7.0))
    _ys, xs = (np.mgrid[0:40, 0:40] + 0.5) * 0.25
    classes = terrain.terrain_class.copy()
    classes[(xs >= 7.0) & (xs < 7.75)] = MUDDY
    planner = Planner(TerrainMap(terrain.elevation_m, classes, terrain.obstacles, 0.25), VehicleParams())
    start = (5.3, 5.0)  # 2.5 m of sand and mud east to firm ground, 2.8 m of sand west
    path = planner.plan(start, (1.0, 5.0))  # west: the mud walls off the east
    assert path.points[1][0] < 2.5  # off the sand to the west
    leg = np.linspace(path.points[0], path.points[1], 50)
    assert all(planner.terrain.terrain_class[planner.terrain.cell_of(*p)] != MUDDY for p in leg)


def _hillside_with_sand_band(sand_y: tuple[float, float]) -> TerrainMap:
    """A 10 x 10 m hillside rising north at 20 deg, sandy across its whole width for y in ``sand_y`` (the
    table's sand climbs 12.6 deg with the margin), firm above and below (firm takes 20 deg). Steep enough that
    every way up to the firm ground within reach climbs past the sand's 12.6 deg, even slanting: a way
    slanting up at a grade the sand climbs would be one (the planner's own model of the class)."""
    ys, _xs = (np.mgrid[0:40, 0:40] + 0.5) * 0.25
    classes = np.where((ys >= sand_y[0]) & (ys < sand_y[1]), SANDY, FIRM).astype(np.uint8)
    return TerrainMap(ys * math.tan(math.radians(20.0)), classes, np.zeros((40, 40), dtype=bool), 0.25)


def test_the_way_off_a_slope_goes_down_it_before_up_it():
    """The firm ground uphill is nearer (2.1 m) than the firm ground downhill (2.9 m): a way up the sand is
    the climb its believed grip cannot make (20 deg against 12.6 deg), so the way off goes down to the
    firm ground south."""
    planner = Planner(_hillside_with_sand_band((2.5, 7.5)), VehicleParams())
    start = (5.0, 5.4)
    assert not np.isfinite(planner.cost_grid[planner.terrain.cell_of(*start)])
    path = planner.plan(start, (5.0, 1.0))
    assert tuple(path.points[0]) == start
    assert path.cells[0][0] < 10  # the first cell: off the sand to the south, downhill
    assert planner.terrain.terrain_class[path.cells[0]] == FIRM


def test_the_way_off_a_slope_climbs_when_no_other_is_within_reach():
    """Firm ground only uphill within reach (the sand runs 5.5 m below the rover): the way off climbs to it,
    as before, rather than no way at all."""
    planner = Planner(_hillside_with_sand_band((0.0, 7.5)), VehicleParams())
    path = planner.plan((5.0, 5.4), (5.0, 9.0))
    assert path.cells[0][0] >= 30  # the first cell: the firm ground north, uphill
