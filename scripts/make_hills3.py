"""Write ``scenarios/hills-3.elevation.npy``: a twisted side-slope band along the direct line of hills-3.

The start-goal line y = LINE_Y runs along a contour (elevation 0 on it everywhere), so a rover on the line
never climbs: it only rolls. Across a band a few metres wide the ground is tilted about the line,
``z = (y - LINE_Y) tan(theta(x)) window(y)``, with the tilt theta rising from 0 to PEAK_TILT_DEG (past the
rover's ~42.5 deg static roll limit) and back along x. Outside the band the map is flat, so a planner that
counts slopes can go round. Deterministic: no randomness, same file every run.

Run from the repository root: ``.venv/bin/python scripts/make_hills3.py``.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

RESOLUTION_M = 0.25
SIZE_M = (50.0, 24.0)  # east, north: the map of hills-1 and hills-2
LINE_Y = 12.0  # the start-goal line (scenarios/hills-3.toml)
PEAK_TILT_DEG = 55.0
TILT_RISE_X = (12.0, 17.0)  # the tilt rises from 0 to its peak over this stretch of x ...
TILT_FALL_X = (33.0, 38.0)  # ... holds, then falls back to 0 over this one
BAND_FLAT_HALF_M = 1.5  # full tilt within this distance of the line ...
BAND_EDGE_HALF_M = 3.0  # ... fading to flat ground at this distance
OUTPUT = Path(__file__).resolve().parent.parent / "scenarios" / "hills-3.elevation.npy"

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
    np.save(OUTPUT, layer)
    log.info("wrote %s: %s cells, elevation %.2f to %.2f m", OUTPUT, layer.shape, layer.min(), layer.max())


if __name__ == "__main__":
    main()
