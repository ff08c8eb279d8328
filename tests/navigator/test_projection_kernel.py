"""The compiled nearest-segment search gives the numpy formulation's numbers to the bit."""

from __future__ import annotations

import numpy as np

from navigator.projection_kernel import MIN_LENGTH_SQ, nearest_segment


def _numpy_nearest(points: np.ndarray, first: int, last: int, x: float, y: float) -> tuple[float, ...]:
    """The follower's projection as it was written in numpy (the reference)."""
    starts, ends = points[first:last], points[first + 1 : last + 1]
    deltas = ends - starts
    lengths_sq = np.maximum(np.sum(deltas * deltas, axis=1), MIN_LENGTH_SQ)
    t = np.clip(np.sum((np.array([x, y]) - starts) * deltas, axis=1) / lengths_sq, 0.0, 1.0)
    nearest = starts + t[:, np.newaxis] * deltas
    best = int(np.argmin(np.hypot(*(np.array([x, y]) - nearest).T)))
    return (
        first + best, t[best], *nearest[best], *deltas[best], lengths_sq[best]
    )  # fmt: skip


def test_matches_numpy_on_random_paths_and_corners() -> None:
    rng = np.random.default_rng(7)
    for _ in range(300):
        # Grid-like paths (cell centres, repeated points, sharp corners) and random ones.
        steps = rng.integers(-1, 2, size=(rng.integers(2, 30), 2)) * 0.25
        grid = np.cumsum(np.vstack([[0.0, 0.0], steps]), axis=0) + rng.normal(size=2)
        loose = np.cumsum(rng.normal(size=(rng.integers(2, 30), 2)), axis=0)
        for points in (grid, loose):
            first = int(rng.integers(0, len(points) - 1))
            last = int(rng.integers(first + 1, len(points)))
            # Poses near a vertex land in corner wedges where two segments are (almost) equally near.
            vertex = points[rng.integers(first, last + 1)]
            for x, y in (vertex + rng.normal(scale=0.3, size=2), rng.normal(scale=5.0, size=2)):
                got = nearest_segment(points, first, last, float(x), float(y))
                assert got == _numpy_nearest(points, first, last, float(x), float(y))
