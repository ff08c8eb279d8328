"""The believed terrain map as a ``foxglove.Grid`` message (topic ``navigator/map``).

Three float32 fields per cell, little-endian: elevation (m), terrain class id, obstacle (0 or 1).
Rows run south to north and columns west to east, as in ``TerrainMap``; the grid's pose is the map's
south-west corner in ENU.
"""

from __future__ import annotations

import base64
from typing import Any

import numpy as np

from logs import topics
from navigator.terrain import TerrainMap

# foxglove.NumericType FLOAT32
_FLOAT32 = 7
_FIELDS = ("elevation", "terrain_class", "obstacle")


def grid_message(terrain: TerrainMap, t_ns: int) -> dict[str, Any]:
    rows, cols = terrain.shape
    cells = np.empty((rows, cols, len(_FIELDS)), dtype="<f4")
    cells[..., 0] = terrain.elevation_m
    cells[..., 1] = terrain.terrain_class
    cells[..., 2] = terrain.obstacles
    cell_stride = 4 * len(_FIELDS)
    return {
        "timestamp": topics.stamp(t_ns),
        "frame_id": topics.ENU_FRAME,
        "pose": topics.planar_pose(terrain.origin_xy[0], terrain.origin_xy[1], 0.0),
        "column_count": cols,
        "cell_size": {"x": terrain.resolution_m, "y": terrain.resolution_m},
        "row_stride": cols * cell_stride,
        "cell_stride": cell_stride,
        "fields": [{"name": name, "offset": 4 * i, "type": _FLOAT32} for i, name in enumerate(_FIELDS)],
        "data": base64.b64encode(cells.tobytes()).decode("ascii"),
    }
