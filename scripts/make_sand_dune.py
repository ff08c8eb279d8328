"""Write the sand-dune scenario's layers (``scenarios/sand-dune.*.npy``): a sandy dune across the direct line.

Firm, flat ground 40 x 30 m, crossed at x 15-25 m by a sandy dune whose flanks rise at ``FLANK_DEG`` to a
ridge along x = 20 m. The dune spans y 0 to ``DUNE_END_Y`` m; north of it a firm, flat gap lets a rover go
round. A flank of 11 deg is within what sand of the built-in table lets the rover climb (atan(mu - crr) =
atan(0.40 - 0.12) = 15.6 deg) and past what the scenario's measured sand does (atan(0.25 - 0.12) = 7.4
deg): the planner that believes the table drives over it; one that believes the measured figure goes
round. Deterministic: no randomness, same files every run.

Run from the repository root: ``.venv/bin/python scripts/make_sand_dune.py``.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np

SIZE_M = (40.0, 30.0)  # x, y
RESOLUTION_M = 0.25
RIDGE_X_M = 20.0
HALF_WIDTH_M = 5.0  # the dune's foot is this far either side of its ridge
FLANK_DEG = 11.0
DUNE_END_Y_M = 27.0  # the dune runs from y = 0 to here; the gap north of it is firm and flat
SANDY, FIRM = 2, 0  # navigator.terrain_classes ids
FOLDER = Path(__file__).resolve().parent.parent / "scenarios"

log = logging.getLogger(__name__)


def layers() -> tuple[np.ndarray, np.ndarray]:
    """(elevation m, class ids), row 0 = south, cell centres at (i + 0.5) x resolution."""
    cols, rows = round(SIZE_M[0] / RESOLUTION_M), round(SIZE_M[1] / RESOLUTION_M)
    xs = (np.arange(cols) + 0.5) * RESOLUTION_M
    ys = (np.arange(rows) + 0.5) * RESOLUTION_M
    height = np.maximum(HALF_WIDTH_M - np.abs(xs - RIDGE_X_M), 0.0) * math.tan(math.radians(FLANK_DEG))
    on_dune = (np.abs(xs - RIDGE_X_M) < HALF_WIDTH_M)[np.newaxis, :] & (ys < DUNE_END_Y_M)[:, np.newaxis]
    elevation = np.where(on_dune, height[np.newaxis, :], 0.0)
    classes = np.where(on_dune, SANDY, FIRM).astype(np.uint8)
    return elevation, classes


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    elevation, classes = layers()
    np.save(FOLDER / "sand-dune.elevation.npy", elevation)
    np.save(FOLDER / "sand-dune.classes.npy", classes)
    log.info("wrote sand-dune layers: %s cells, dune %.2f m high", elevation.shape, elevation.max())


if __name__ == "__main__":
    main()
