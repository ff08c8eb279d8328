"""Distance driven along a recorded trajectory, robust to the jitter of an estimated one.

The ground truth (``truth/pose``) moves only when the rover does, so summing its position steps is exact.
The estimate (``estimator/pose``) jitters with GPS noise: summing its steps counts every jump as travel
(1.5 m "driven" during a 2 s standstill, +11 % over a 29 m trial), so for the estimate the distance is
the estimator's own speed integrated over time, ``sum (|v_{k-1}| + |v_k|) / 2 * dt_k``, which stays
near zero at a standstill and is within ~0.3 % of the truth while driving (docs/metrics.md).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def step_lengths(xy: FloatArray) -> FloatArray:
    """|p_k - p_{k-1}| (m) for k = 1..N of a trajectory of shape (N + 1, 2)."""
    if len(xy) < 2:
        return np.zeros(0)
    return np.asarray(np.hypot(*np.diff(xy, axis=0).T), dtype=np.float64)


def speed_steps(t_s: FloatArray, speed_mps: FloatArray) -> FloatArray:
    """Distance (m) driven over each interval, the trapezoid rule over |speed| (sign: reversing counts)."""
    if len(t_s) < 2:
        return np.zeros(0)
    magnitude = np.abs(speed_mps)
    return np.asarray(0.5 * (magnitude[1:] + magnitude[:-1]) * np.diff(t_s), dtype=np.float64)


def travel_steps(t_s: FloatArray, xy: FloatArray, speed_mps: FloatArray | None) -> FloatArray:
    """Distance driven over each interval: from ``speed_mps`` when given (an estimate), and finite at
    every sample, else the position steps (the truth, or an estimate recorded without its speed)."""
    if speed_mps is not None and len(speed_mps) == len(t_s) and bool(np.all(np.isfinite(speed_mps))):
        return speed_steps(t_s, speed_mps)
    return step_lengths(xy)


def cumulative(steps: FloatArray) -> FloatArray:
    """Distance driven from the first sample to each sample (m), starting at 0."""
    return np.concatenate([[0.0], np.cumsum(steps)])
