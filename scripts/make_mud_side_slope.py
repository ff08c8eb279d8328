"""Write ``tests/data/mud_side_slope.{elevation,classes}.npy``: a small muddy side-slope band.

hills-3's shape (``scripts/make_hills3.py``) at a mud-sized tilt: the start-goal line y = LINE_Y runs along
a contour, and across a band about it the ground is tilted by ``theta(x)``, rising from 0 to PEAK_TILT_DEG
and back along x, ``z = (y - LINE_Y) tan(theta(x)) window(y)``; flat mud beyond. The peak tilt, 16 deg, is
one a parked rover holds on mud (atan mu = 16.7 deg) but a driving one does not: its wheels' pull against
rolling resistance leaves sideways ``sqrt(mu^2 - crr^2)`` = tan 14.6 deg (docs/physics.md), so it slides
downhill while it drives along the line. Deterministic: no randomness, same files every run.

Run from the repository root: ``.venv/bin/python scripts/make_mud_side_slope.py``.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

RESOLUTION_M = 0.25
SIZE_M = (14.0, 12.0)  # east, north
LINE_Y = 6.0  # the start-goal line (tests/data/mud_side_slope.toml)
PEAK_TILT_DEG = 16.0
TILT_RISE_X = (3.0, 5.0)  # the tilt rises from 0 to its peak over this stretch of x ...
TILT_FALL_X = (9.5, 11.5)  # ... holds, then falls back to 0 over this one
BAND_FLAT_HALF_M = 1.5  # full tilt within this distance of the line ...
BAND_EDGE_HALF_M = 3.0  # ... fading to flat ground at this distance
MUDDY = 3  # navigator.terrain_classes
DATA = Path(__file__).resolve().parent.parent / "tests" / "data"

log = logging.getLogger(__name__)


def smoothstep(t: NDArray[np.float64]) -> NDArray[np.float64]:
    """0 below 0, 1 above 1, a C1 cubic between."""
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def tilt_rad(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """The band's tilt about the line at each x (rad)."""
    rise = smoothstep((x - TILT_RISE_X[0]) / (TILT_RISE_X[1] - TILT_RISE_X[0]))
    fall = 1.0 - smoothstep((x - TILT_FALL_X[0]) / (TILT_FALL_X[1] - TILT_FALL_X[0]))
    return np.radians(PEAK_TILT_DEG) * rise * fall


def band_window(y: NDArray[np.float64]) -> NDArray[np.float64]:
    """1 near the line, 0 beyond the band's edge."""
    distance = np.abs(y - LINE_Y)
    return 1.0 - smoothstep((distance - BAND_FLAT_HALF_M) / (BAND_EDGE_HALF_M - BAND_FLAT_HALF_M))


def elevation() -> NDArray[np.float64]:
    """(rows, cols) elevation in metres, cell centres at (col + 0.5, row + 0.5) * RESOLUTION_M."""
    cols, rows = round(SIZE_M[0] / RESOLUTION_M), round(SIZE_M[1] / RESOLUTION_M)
    x = (np.arange(cols) + 0.5) * RESOLUTION_M
    y = (np.arange(rows) + 0.5) * RESOLUTION_M
    xs, ys = np.meshgrid(x, y)
    return (ys - LINE_Y) * np.tan(tilt_rad(xs)) * band_window(ys)


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    layer = elevation()
    np.save(DATA / "mud_side_slope.elevation.npy", layer)
    np.save(DATA / "mud_side_slope.classes.npy", np.full(layer.shape, MUDDY, np.uint8))
    log.info("wrote %s cells, elevation %.2f to %.2f m", layer.shape, layer.min(), layer.max())


if __name__ == "__main__":
    main()
