"""The follower's nearest-segment search compiled with numba: one call instead of a dozen numpy calls.

``PurePursuit`` projects the rover on a window of path segments every control tick (50 Hz). In numpy that
was ~15 small-array operations, each a microsecond or more of call overhead, for a window of ten or twenty
segments: most of the follower's time. The loop below does the same arithmetic in the same order (so the
same floats come out, to the bit: ``np.hypot`` and numba's ``math.hypot`` are both the C library's
``hypot``; Python's own ``math.hypot`` is not, and rounds differently about once in 300 calls, which can
flip the choice between two segments equally near at a corner). Cached on disk (``cache=True``).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

# Segments shorter than this (squared, m^2) are treated as this long: a repeated point cannot divide by 0.
MIN_LENGTH_SQ = 1e-12


@numba.njit(cache=True, nogil=True)
def nearest_segment(
    points: NDArray[np.float64], first: int, last: int, x: float, y: float
) -> tuple[int, float, float, float, float, float, float]:
    """The segment of ``points[first:last + 1]`` (shape (n, 2), ENU m) nearest to (x, y); the first on ties.

    Returns (segment index, t in [0, 1] along it, nearest point x, y, segment dx, dy, squared length
    clamped to ``MIN_LENGTH_SQ``). Needs ``first < last``.
    """
    best = -1
    best_distance = math.inf
    result = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    for i in range(first, last):
        sx, sy = points[i, 0], points[i, 1]
        dx, dy = points[i + 1, 0] - sx, points[i + 1, 1] - sy
        length_sq = max(dx * dx + dy * dy, MIN_LENGTH_SQ)
        t = min(max(((x - sx) * dx + (y - sy) * dy) / length_sq, 0.0), 1.0)
        nx, ny = sx + t * dx, sy + t * dy
        distance = math.hypot(x - nx, y - ny)
        if distance < best_distance:
            best, best_distance = i, distance
            result = (t, nx, ny, dx, dy, length_sq)
    t, nx, ny, dx, dy, length_sq = result
    return best, t, nx, ny, dx, dy, length_sq
