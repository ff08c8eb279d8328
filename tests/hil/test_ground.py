"""The one-call ground look-up gives the terrain map's own numbers, to the last bit."""

import math

import numpy as np
import pytest

from hil.ground import GroundProbe
from navigator.errors import TerrainError
from navigator.terrain import TerrainMap


def _hilly_map() -> TerrainMap:
    rng = np.random.default_rng(7)
    rows, cols = 23, 31
    yy, xx = np.mgrid[0:rows, 0:cols]
    elevation = 0.8 * np.sin(xx / 4.0) * np.cos(yy / 5.0) + rng.normal(0.0, 0.05, (rows, cols))
    classes = rng.integers(0, 6, (rows, cols))
    return TerrainMap(elevation, classes, np.zeros((rows, cols), dtype=bool), 0.3, origin_xy=(-2.5, 4.0))


def test_matches_the_maps_class_elevation_and_tilt_exactly():
    terrain = _hilly_map()
    probe = GroundProbe(terrain)
    rng = np.random.default_rng(3)
    width, height = terrain.size_m
    ox, oy = terrain.origin_xy
    res = terrain.resolution_m
    rows, cols = terrain.shape
    points = [
        (ox + rng.uniform(0.0, width), oy + rng.uniform(0.0, height), rng.uniform(-4.0, 4.0))
        for _ in range(2000)
    ]
    # Cell edges, cell centres and the outer margins (bilinear held constant past the outer centres).
    points += [(ox + c * res, oy + (r + 0.5) * res, 0.7) for r in range(rows) for c in range(cols)]
    points += [
        (ox, oy, -1.0),
        (ox + width - 1e-9, oy + height - 1e-9, 2.0),
        (ox + 0.01, oy + height - 0.01, 3.0),
    ]
    for x, y, yaw in points:
        under = probe.at(x, y, yaw)
        assert under.terrain_class == terrain.class_at(x, y)
        assert under.elevation_m == terrain.elevation_at(x, y)
        assert (under.roll_rad, under.pitch_rad) == terrain.tilt_at(x, y, yaw)


@pytest.mark.parametrize(
    ("x", "y"), [(-2.6, 5.0), (7.0, 3.9), (100.0, 5.0), (math.nan, 5.0), (0.0, math.inf)]
)
def test_off_the_map_is_the_maps_error(x, y):
    with pytest.raises(TerrainError, match="off the map"):
        GroundProbe(_hilly_map()).at(x, y, 0.0)
