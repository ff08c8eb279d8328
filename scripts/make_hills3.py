"""Write ``scenarios/hills-3.elevation.npy``: a twisted side-slope band along the direct line of hills-3.

The start-goal line y = 12 m runs along a contour of a band (``scripts/side_slope_band.py``) a few metres
wide, tilted about the line by up to 55 deg (past the rover's ~42.5 deg static roll limit) and back along x.
Outside the band the map is flat, so a planner that counts slopes can go round. Deterministic: no
randomness, same file every run.

Run from the repository root: ``.venv/bin/python scripts/make_hills3.py``.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from side_slope_band import SideSlopeBand, elevation

BAND = SideSlopeBand(
    size_m=(50.0, 24.0),  # the map of hills-1 and hills-2
    line_y=12.0,  # the start-goal line (scenarios/hills-3.toml)
    peak_tilt_deg=55.0,
    tilt_rise_x=(12.0, 17.0),
    tilt_fall_x=(33.0, 38.0),
)
OUTPUT = Path(__file__).resolve().parent.parent / "scenarios" / "hills-3.elevation.npy"

log = logging.getLogger(__name__)


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    layer = elevation(BAND)
    np.save(OUTPUT, layer)
    log.info("wrote %s: %s cells, elevation %.2f to %.2f m", OUTPUT, layer.shape, layer.min(), layer.max())


if __name__ == "__main__":
    main()
