"""The terrain under a point in one compiled call: its class, elevation, roll and pitch.

``TerrainMap.ground_at`` (and through it ``elevation_at`` and ``tilt_at``) runs this kernel: the cell of a
point, bilinear interpolation between cell centres (held constant past the outer centres) on the map's
precomputed gradient, and the exact yaw-pitch-roll of a body on that plane. The simulator asks it once
per physics step; numpy scalar indexing for the same answers cost about a fifth of a step.
``tests/navigator/test_ground_at.py`` checks it against a plain numpy reference, edges included.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray


class GroundUnder(NamedTuple):
    """The terrain at one point, for a rover heading ``yaw`` there (angles as ``TerrainMap.tilt_at``)."""

    terrain_class: int
    elevation_m: float
    roll_rad: float
    pitch_rad: float


@numba.njit(cache=True)
def _bilinear(
    layer: NDArray[np.float64], origin_x: float, origin_y: float, resolution: float, x: float, y: float
) -> float:
    """Between cell centres, held constant past the outer centres."""
    rows, cols = layer.shape
    fx = min(max((x - origin_x) / resolution - 0.5, 0.0), cols - 1.0)
    fy = min(max((y - origin_y) / resolution - 0.5, 0.0), rows - 1.0)
    c0, r0 = int(fx), int(fy)
    c1, r1 = min(c0 + 1, cols - 1), min(r0 + 1, rows - 1)
    tx, ty = fx - c0, fy - r0
    south = (1.0 - tx) * layer[r0, c0] + tx * layer[r0, c1]
    north = (1.0 - tx) * layer[r1, c0] + tx * layer[r1, c1]
    return (1.0 - ty) * south + ty * north


@numba.njit(cache=True)
def ground_at_kernel(
    classes: NDArray[np.uint8],
    elevation: NDArray[np.float64],
    grad_x: NDArray[np.float64],
    grad_y: NDArray[np.float64],
    origin_x: float,
    origin_y: float,
    resolution: float,
    x: float,
    y: float,
    yaw: float,
) -> tuple[int, float, float, float]:
    """(class id, elevation, roll, pitch) at (x, y); class id -1 when the point is off the map."""
    rows, cols = classes.shape
    dx, dy = x - origin_x, y - origin_y
    # As TerrainMap.contains (a NaN fails every comparison, so it is off the map too).
    if not (0.0 <= dx < cols * resolution and 0.0 <= dy < rows * resolution):
        return -1, 0.0, 0.0, 0.0
    col = min(int(dx // resolution), cols - 1)
    row = min(int(dy // resolution), rows - 1)
    gx = _bilinear(grad_x, origin_x, origin_y, resolution, x, y)
    gy = _bilinear(grad_y, origin_x, origin_y, resolution, x, y)
    cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
    slope_forward = gx * cos_yaw + gy * sin_yaw
    slope_left = -gx * sin_yaw + gy * cos_yaw
    pitch = math.atan(slope_forward)
    roll = math.atan2(slope_left, math.sqrt(1.0 + slope_forward * slope_forward))
    height = _bilinear(elevation, origin_x, origin_y, resolution, x, y)
    return int(classes[row, col]), height, roll, pitch
