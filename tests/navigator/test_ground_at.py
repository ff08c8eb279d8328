"""The compiled ground look-up (``TerrainMap.ground_at``, behind ``elevation_at`` and ``tilt_at``) against a
plain numpy reference of the same laws written here, to the last bit."""

import math

import numpy as np
import pytest

from navigator.errors import TerrainError
from navigator.terrain import TerrainMap


def _hilly_map() -> TerrainMap:
    rng = np.random.default_rng(7)
    rows, cols = 23, 31
    yy, xx = np.mgrid[0:rows, 0:cols]
    elevation = 0.8 * np.sin(xx / 4.0) * np.cos(yy / 5.0) + rng.normal(0.0, 0.05, (rows, cols))
    classes = rng.integers(0, 6, (rows, cols))
    return TerrainMap(elevation, classes, np.zeros((rows, cols), dtype=bool), 0.3, origin_xy=(-2.5, 4.0))


def _bilinear(terrain: TerrainMap, layer: np.ndarray, x: float, y: float) -> float:
    rows, cols = terrain.shape
    fx = min(max((x - terrain.origin_xy[0]) / terrain.resolution_m - 0.5, 0.0), cols - 1.0)
    fy = min(max((y - terrain.origin_xy[1]) / terrain.resolution_m - 0.5, 0.0), rows - 1.0)
    c0, r0 = int(fx), int(fy)
    c1, r1 = min(c0 + 1, cols - 1), min(r0 + 1, rows - 1)
    tx, ty = fx - c0, fy - r0
    south = (1.0 - tx) * layer[r0, c0] + tx * layer[r0, c1]
    north = (1.0 - tx) * layer[r1, c0] + tx * layer[r1, c1]
    return float((1.0 - ty) * south + ty * north)


def _reference(terrain: TerrainMap, x: float, y: float, yaw: float) -> tuple[int, float, float, float]:
    """Class of the cell, bilinear elevation, and the yaw-pitch-roll of a body on the gradient's plane."""
    grad_x, grad_y = terrain.slope_gradient()
    gx, gy = _bilinear(terrain, grad_x, x, y), _bilinear(terrain, grad_y, x, y)
    forward = gx * math.cos(yaw) + gy * math.sin(yaw)
    left = -gx * math.sin(yaw) + gy * math.cos(yaw)
    pitch = math.atan(forward)
    roll = math.atan2(left, math.sqrt(1.0 + forward * forward))
    class_id = int(terrain.terrain_class[terrain.cell_of(x, y)])
    return class_id, _bilinear(terrain, terrain.elevation_m, x, y), roll, pitch


def test_matches_the_numpy_reference_exactly():
    terrain = _hilly_map()
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
        under = terrain.ground_at(x, y, yaw)
        class_id, elevation, roll, pitch = _reference(terrain, x, y, yaw)
        assert under.terrain_class == class_id == terrain.class_at(x, y)
        assert under.elevation_m == elevation == terrain.elevation_at(x, y)
        assert (under.roll_rad, under.pitch_rad) == (roll, pitch) == terrain.tilt_at(x, y, yaw)


@pytest.mark.parametrize(
    ("x", "y"), [(-2.6, 5.0), (7.0, 3.9), (100.0, 5.0), (math.nan, 5.0), (0.0, math.inf)]
)
def test_off_the_map_is_the_maps_error(x, y):
    with pytest.raises(TerrainError, match="off the map"):
        _hilly_map().ground_at(x, y, 0.0)
