"""A start inside an obstacle's clearance band plans out of it; a start inside an obstacle does not."""

from __future__ import annotations

import numpy as np
import pytest

from navigator.errors import PlanningError
from navigator.planner import Planner
from navigator.terrain import TerrainMap
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
