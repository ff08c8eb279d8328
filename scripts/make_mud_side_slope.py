"""Write ``tests/data/mud_side_slope.{elevation,classes}.npy``: a small muddy side-slope band.

hills-3's shape (``scripts/side_slope_band.py``) at a mud-sized tilt: the start-goal line y = 6 m runs
along a contour, and across a band about it the ground is tilted, rising from 0 to 16 deg and back along
x; flat mud beyond. The peak tilt, 16 deg, is one a parked rover holds on mud (atan mu = 16.7 deg) but a
driving one does not: its wheels' pull against rolling resistance leaves sideways ``sqrt(mu^2 - crr^2)`` =
tan 14.6 deg (docs/physics.md), so it slides downhill while it drives along the line. Deterministic: no
randomness, same files every run.

Run from the repository root: ``.venv/bin/python scripts/make_mud_side_slope.py``.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from side_slope_band import SideSlopeBand, elevation

BAND = SideSlopeBand(
    size_m=(14.0, 12.0),
    line_y=6.0,  # the start-goal line (tests/data/mud_side_slope.toml)
    peak_tilt_deg=16.0,
    tilt_rise_x=(3.0, 5.0),
    tilt_fall_x=(9.5, 11.5),
)
MUDDY = 3  # navigator.terrain_classes
DATA = Path(__file__).resolve().parent.parent / "tests" / "data"

log = logging.getLogger(__name__)


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    layer = elevation(BAND)
    np.save(DATA / "mud_side_slope.elevation.npy", layer)
    np.save(DATA / "mud_side_slope.classes.npy", np.full(layer.shape, MUDDY, np.uint8))
    log.info("wrote %s cells, elevation %.2f to %.2f m", layer.shape, layer.min(), layer.max())


if __name__ == "__main__":
    main()
