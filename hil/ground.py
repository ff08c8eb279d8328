"""The true terrain under the rover in one compiled call: its class, elevation, roll and pitch.

Every physics step the simulator asks the terrain the same four questions about the same point (the class
for the wheel-ground laws, the tilt for the loads, the elevation for the autopilot's and the recorder's
truth). ``TerrainMap.class_at``, ``elevation_at`` and ``tilt_at`` answer them one at a time, each finding
the cell again with numpy scalar indexing: together about a fifth of a physics step. ``GroundProbe.at``
answers all four at once with the map's own arithmetic (cell of a point, bilinear between cell centres on
the map's precomputed gradient, the exact yaw-pitch-roll of a body on that plane), so the numbers are the
map's to the last bit; ``tests/hil/test_ground.py`` compares them on random points, edges included.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

from navigator.errors import TerrainError
from navigator.terrain import TerrainMap


class GroundUnder(NamedTuple):
    """The terrain at one point, for a rover heading ``yaw`` there (angles as ``TerrainMap.tilt_at``)."""

    terrain_class: int
    elevation_m: float
    roll_rad: float
    pitch_rad: float


class GroundProbe:
    """Looks up ``GroundUnder`` on one terrain map (build a new probe when the map is swapped)."""

    def __init__(self, terrain: TerrainMap) -> None:
        self._terrain = terrain
        grad_x, grad_y = terrain.slope_gradient()
        self._classes = np.ascontiguousarray(terrain.terrain_class)
        self._elevation = np.ascontiguousarray(terrain.elevation_m)
        self._grad_x = np.ascontiguousarray(grad_x)
        self._grad_y = np.ascontiguousarray(grad_y)
        self._origin_x, self._origin_y = terrain.origin_xy
        self._resolution = terrain.resolution_m

    @property
    def terrain(self) -> TerrainMap:
        return self._terrain

    def at(self, x: float, y: float, yaw: float) -> GroundUnder:
        """Class, elevation (m) and (roll, pitch) in rad at (x, y); TerrainError when it is off the map."""
        class_id, elevation, roll, pitch = _ground_at(
            self._classes,
            self._elevation,
            self._grad_x,
            self._grad_y,
            self._origin_x,
            self._origin_y,
            self._resolution,
            x,
            y,
            yaw,
        )
        if class_id < 0:
            self._terrain.cell_of(x, y)  # raises the map's own error, naming the point and the map's extent
            raise TerrainError(f"point ({x}, {y}) is off the map")  # unreachable: cell_of raised
        return GroundUnder(class_id, elevation, roll, pitch)


@numba.njit(cache=True)
def _bilinear(
    layer: NDArray[np.float64], origin_x: float, origin_y: float, resolution: float, x: float, y: float
) -> float:
    """As ``TerrainMap._bilinear``: between cell centres, held constant past the outer centres."""
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
def _ground_at(
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
