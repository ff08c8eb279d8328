"""Write the sand-side-slope scenario's layers (``scenarios/sand-side-slope.*.npy``): a hillside whose
contour the direct line follows, across a strip of sand.

40 x 50 m rising to the north at ``TILT_DEG`` for y in ``SLOPE_Y_M`` (flat south and north of it), so the
start-goal line y = 25 m runs along a contour; firm ground but for a sandy strip at x ``SAND_X_M`` running
the map's height. A side slope of 12.5 deg is within what sand of the built-in table lets the planner take
(``atan(0.40 - 0.12)`` less its 3 deg margin = 12.6 deg) and past what the scenario's measured sand (mu
0.25) holds a driving rover on (``atan(sqrt(mu^2 - crr^2))`` = 12.4 deg, less where the downhill wheels sink
more: docs/physics.md): the planner that believes the table drives along the contour and slides downhill.
The way round the slope, down to the flat and back up, is 44 m longer than the direct line's 34 m: the
planner takes the line while it believes the sand holds. Deterministic: no randomness, same files every run.

Run from the repository root: ``.venv/bin/python scripts/make_sand_side_slope.py``.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np

SIZE_M = (40.0, 50.0)  # x, y
RESOLUTION_M = 0.25
TILT_DEG = 12.5
SLOPE_Y_M = (3.0, 47.0)  # the hillside between these; flat south and north of it
SAND_X_M = (15.0, 25.0)  # a strip of sand, the map's height
SANDY, FIRM = 2, 0  # navigator.terrain_classes ids
FOLDER = Path(__file__).resolve().parent.parent / "scenarios"

log = logging.getLogger(__name__)


def layers() -> tuple[np.ndarray, np.ndarray]:
    """(elevation m, class ids), row 0 = south, cell centres at (i + 0.5) x resolution."""
    cols, rows = round(SIZE_M[0] / RESOLUTION_M), round(SIZE_M[1] / RESOLUTION_M)
    xs = (np.arange(cols) + 0.5) * RESOLUTION_M
    ys = (np.arange(rows) + 0.5) * RESOLUTION_M
    height = (np.clip(ys, *SLOPE_Y_M) - SLOPE_Y_M[0]) * math.tan(math.radians(TILT_DEG))
    elevation = np.repeat(height[:, np.newaxis], cols, axis=1)
    on_sand = (xs >= SAND_X_M[0]) & (xs < SAND_X_M[1])
    classes = np.where(on_sand[np.newaxis, :], SANDY, FIRM).astype(np.uint8).repeat(rows, axis=0)
    return elevation, classes


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    elevation, classes = layers()
    np.save(FOLDER / "sand-side-slope.elevation.npy", elevation)
    np.save(FOLDER / "sand-side-slope.classes.npy", classes)
    log.info("wrote sand-side-slope layers: %s cells, hillside %.2f m high", elevation.shape, elevation.max())


if __name__ == "__main__":
    main()
