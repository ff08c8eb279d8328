"""Rays from a sensor on the rover against the true obstacles (discs): how far each ray runs before it meets
one. The simulated lidar (``hil.lidar_sim``) casts its 72 sectors with it, the simulated rangefinders
(``hil.rangefinder_sim``) a fan of rays across each beam's cone.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable

import numpy as np
from numpy.typing import NDArray

# (id, x, y, radius, vx, vy) of every obstacle at a clock reading: hil.perception_sim's obstacles_at.
ObstacleTruth = Callable[[int], list[tuple[str, float, float, float, float, float]]]


def nearest_hits(
    sx: float,
    sy: float,
    dx: NDArray[np.float64],
    dy: NDArray[np.float64],
    obstacles: Iterable[tuple[str, float, float, float, float, float]],
    range_m: float,
) -> NDArray[np.float64]:
    """For rays from (``sx``, ``sy``) along the unit vectors (``dx``, ``dy``) (ENU), the distance to the
    nearest obstacle edge each meets: inf where it meets none (obstacles whose near edge lies beyond
    ``range_m`` are not looked at), 0 for every ray when the sensor is inside an obstacle."""
    nearest = np.full(dx.shape, np.inf)
    for _id, ox, oy, radius, _vx, _vy in obstacles:
        cx, cy = ox - sx, oy - sy
        centre = math.hypot(cx, cy)
        if centre - radius > range_m:
            continue
        if centre <= radius:
            nearest[:] = 0.0  # the sensor inside it: every ray starts in the obstacle
            continue
        along = dx * cx + dy * cy  # distance along each ray to its point nearest the centre
        miss_sq = centre * centre - along * along
        inside = radius * radius - miss_sq
        hit = (along > 0.0) & (inside >= 0.0)
        distance = np.where(hit, along - np.sqrt(np.where(hit, inside, 0.0)), np.inf)
        np.minimum(nearest, distance, out=nearest)
    return nearest
