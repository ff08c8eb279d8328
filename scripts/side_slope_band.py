"""A side-slope band about a straight line, the elevation layer of ``scripts/make_hills3.py`` and
``scripts/make_mud_side_slope.py``.

The line y = ``line_y`` runs along a contour (elevation 0 on it everywhere), so a rover on it never climbs:
it only rolls. Across a band about the line the ground is tilted, ``z = (y - line_y) tan(theta(x))
window(y)``: the tilt theta rises from 0 to ``peak_tilt_deg`` over ``tilt_rise_x`` and falls back to 0
over ``tilt_fall_x`` (smoothsteps); the window is 1 within ``band_flat_half_m`` of the line and fades
(smoothstep) to flat ground at ``band_edge_half_m``. Deterministic: no randomness.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class SideSlopeBand:
    """The band's shape; lengths in metres, x east and y north from the map's corner."""

    size_m: tuple[float, float]  # east, north
    line_y: float
    peak_tilt_deg: float
    tilt_rise_x: tuple[float, float]  # the tilt rises from 0 to its peak over this stretch of x ...
    tilt_fall_x: tuple[float, float]  # ... holds, then falls back to 0 over this one
    band_flat_half_m: float = 1.5  # full tilt within this distance of the line ...
    band_edge_half_m: float = 3.0  # ... fading to flat ground at this distance
    resolution_m: float = 0.25


def smoothstep(t: NDArray[np.float64]) -> NDArray[np.float64]:
    """0 below 0, 1 above 1, a C1 cubic between."""
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def tilt_rad(band: SideSlopeBand, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """The band's tilt about the line at each x (rad)."""
    rise = smoothstep((x - band.tilt_rise_x[0]) / (band.tilt_rise_x[1] - band.tilt_rise_x[0]))
    fall = 1.0 - smoothstep((x - band.tilt_fall_x[0]) / (band.tilt_fall_x[1] - band.tilt_fall_x[0]))
    return np.radians(band.peak_tilt_deg) * rise * fall


def band_window(band: SideSlopeBand, y: NDArray[np.float64]) -> NDArray[np.float64]:
    """1 near the line, 0 beyond the band's edge."""
    distance = np.abs(y - band.line_y)
    return 1.0 - smoothstep(
        (distance - band.band_flat_half_m) / (band.band_edge_half_m - band.band_flat_half_m)
    )


def elevation(band: SideSlopeBand) -> NDArray[np.float64]:
    """(rows, cols) elevation in metres, cell centres at (col + 0.5, row + 0.5) * resolution."""
    res = band.resolution_m
    cols, rows = round(band.size_m[0] / res), round(band.size_m[1] / res)
    x = (np.arange(cols) + 0.5) * res
    y = (np.arange(rows) + 0.5) * res
    xs, ys = np.meshgrid(x, y)
    return (ys - band.line_y) * np.tan(tilt_rad(band, xs)) * band_window(band, ys)
