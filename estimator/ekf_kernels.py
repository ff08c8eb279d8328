"""The EKF arithmetic compiled with numba: predict and the gated update over plain arrays, in place.

A 7-state EKF step is a few hundred flops; in numpy each of its dozen small-matrix operations costs a
microsecond of call overhead, which is most of the time. Compiled, a whole predict or update is one call,
and a gyro or odometry sample (predict to its time, then its update: two of every control tick's three
samples) is one call too (``gyro_kernel``, ``odometry_kernel``): the same arithmetic in the same order as
``predict_kernel`` then ``update_kernel`` called one after the other.
Kernels are cached on disk (``cache=True``), so only the first run on a machine pays the compilation.
The arithmetic is the textbook EKF (see ``estimator.ekf`` for the model and the units).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

# State indices, repeated here so the kernels see compile-time constants (they match estimator.ekf).
_X, _Y, _YAW, _SPEED, _YAW_RATE, _BIAS, _SCALE = 0, 1, 2, 3, 4, 5, 6
_TWO_PI = 2.0 * math.pi
# Constant model arrays, read by the kernels as globals (numba freezes them into the compiled code): each
# array argument costs the per-call dispatch a type check and an unboxing, on every control tick.
# The random-walk states, in the order of the process noise intensities (``q_rate``).
WALK_STATES = np.array([_SPEED, _YAW_RATE, _BIAS, _SCALE], dtype=np.int64)
H_GYRO = np.array([[0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0]])  # the gyro sees yaw rate + bias


@numba.njit(cache=True)
def _wrap(angle: float) -> float:
    wrapped = angle - _TWO_PI * math.floor((angle + math.pi) / _TWO_PI)  # [-pi, pi)
    return math.pi if wrapped == -math.pi else wrapped


# The matrix products below are explicit loops with fastmath "contract" only (no reassociation): each entry
# is the products summed in the same order as before, k = 0..K-1, each product fused into the sum (one
# rounding per step), which is how BLAS's dgemm (what ``a @ b`` called) sums them on a CPU with FMA; a
# test compares the two. Why not BLAS: a predict runs once per control tick after the rest of the tick has
# pushed BLAS's code and buffers out of the cache, and its two 7 x 7 dgemm calls then cost ~10 us against
# a few us for these loops. The same loops in ``update_kernel`` (P H^T, H P H^T, the gain) stay unfused:
# they were loops before, without FMA, and must keep their floats, so they cannot share this function.
@numba.njit(cache=True, fastmath={"contract"})
def _product(a: Array, b: Array) -> Array:
    """``a @ b``, as explicit loops (``b`` may be a transposed view: ``_product(a, b.T)`` is ``a @ b.T``)."""
    rows, inner, columns = a.shape[0], a.shape[1], b.shape[1]
    out = np.empty((rows, columns))
    for i in range(rows):
        for j in range(columns):
            acc = 0.0
            for c in range(inner):
                acc += a[i, c] * b[c, j]
            out[i, j] = acc
    return out


@numba.njit(cache=True)
def predict_kernel(x: Array, p: Array, dt: float, q_rate: Array, accel: float) -> None:
    """Constant yaw rate over ``dt`` (s), mid-interval heading; the speed constant too, or changing at the
    measured body acceleration ``accel`` (m/s^2) when it is not 0; P = F P F^T + Q dt, in place.

    ``accel`` is an input, not a state: F is the same either way (the speed's own uncertainty still grows
    by its random walk, which covers the acceleration's error too)."""
    n = x.shape[0]
    v = x[_SPEED]
    w = x[_YAW_RATE]
    heading = x[_YAW] + 0.5 * w * dt
    cos_h = math.cos(heading)
    sin_h = math.sin(heading)
    if accel != 0.0:  # a branch, not a zero term: without an input the floats are exactly as before
        step = (v + 0.5 * accel * dt) * dt
        x[_SPEED] = v + accel * dt
    else:
        step = v * dt
    x[_X] += step * cos_h
    x[_Y] += step * sin_h
    x[_YAW] = _wrap(x[_YAW] + w * dt)
    f = np.eye(n)
    f[_X, _YAW] = -step * sin_h
    f[_X, _SPEED] = dt * cos_h
    f[_X, _YAW_RATE] = -step * sin_h * 0.5 * dt
    f[_Y, _YAW] = step * cos_h
    f[_Y, _SPEED] = dt * sin_h
    f[_Y, _YAW_RATE] = step * cos_h * 0.5 * dt
    f[_YAW, _YAW_RATE] = dt
    new = _product(_product(f, p), f.T)  # F P F^T
    for i in range(WALK_STATES.shape[0]):
        s = WALK_STATES[i]
        new[s, s] += q_rate[i] * dt
    for i in range(n):  # symmetrise: F P F^T is symmetric in exact arithmetic only
        for j in range(i + 1, n):
            mean = 0.5 * (new[i, j] + new[j, i])
            new[i, j] = mean
            new[j, i] = mean
    # Element by element: a slice assignment (p[:, :] = new) compiles numba's shape-mismatch message, ~8 s
    # of every cold start's compile for a copy whose shapes cannot differ.
    for i in range(n):
        for j in range(n):
            p[i, j] = new[i, j]


@numba.njit(cache=True)
def update_kernel(
    x: Array, p: Array, y: Array, h: Array, r: Array, gate: float, gated: bool, schmidt_state: int
) -> tuple[float, bool]:
    """Gate on NIS, then update x and P in place; returns (NIS, accepted).

    ``schmidt_state`` >= 0 names a state that is only *considered*: its gain row is zeroed and the
    covariance then takes the Joseph form (K is no longer optimal).
    """
    n = x.shape[0]
    m = y.shape[0]
    # Explicit loops: for 7 x (1 or 2) matrices they beat BLAS calls and allocate almost nothing.
    pht = np.zeros((n, m))
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for c in range(n):
                acc += p[i, c] * h[j, c]
            pht[i, j] = acc
    s = r.copy()
    for i in range(m):
        for j in range(m):
            acc = 0.0
            for c in range(n):
                acc += h[i, c] * pht[c, j]
            s[i, j] += acc
    s_inv = np.empty((m, m))
    if m == 1:
        s_inv[0, 0] = 1.0 / s[0, 0]
    elif m == 2:
        det = s[0, 0] * s[1, 1] - s[0, 1] * s[1, 0]
        s_inv[0, 0] = s[1, 1] / det
        s_inv[1, 1] = s[0, 0] / det
        s_inv[0, 1] = -s[0, 1] / det
        s_inv[1, 0] = -s[1, 0] / det
    else:
        raise ValueError("update_kernel handles measurements of 1 or 2 rows")
    nis = 0.0
    for i in range(m):
        for j in range(m):
            nis += y[i] * s_inv[i, j] * y[j]
    if not math.isfinite(nis) or (gated and nis > gate):
        return nis, False
    k = np.zeros((n, m))
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for c in range(m):
                acc += pht[i, c] * s_inv[c, j]
            k[i, j] = acc
    if schmidt_state >= 0:
        k[schmidt_state, :] = 0.0
    for i in range(n):
        for j in range(m):
            x[i] += k[i, j] * y[j]
    x[_YAW] = _wrap(x[_YAW])
    if schmidt_state >= 0:
        i_kh = np.eye(n) - _product(k, h)
        new = _product(_product(i_kh, p), i_kh.T) + _product(_product(k, r), k.T)  # Joseph form
        for i in range(n):
            for j in range(n):
                p[i, j] = 0.5 * (new[i, j] + new[j, i])
        return nis, True
    # P - K (P H^T)^T, written into the upper triangle and mirrored: symmetric by construction.
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for c in range(m):
                acc += k[i, c] * pht[j, c]
            value = p[i, j] - acc
            p[i, j] = value
            p[j, i] = value
    return nis, True


@numba.njit(cache=True)
def gyro_kernel(
    x: Array,
    p: Array,
    dt: float,
    q_rate: Array,
    accel: float,
    z_rps: float,
    y: Array,
    r: Array,
    gate: float,
    schmidt_state: int,
) -> tuple[float, bool]:
    """Predict over ``dt`` (s; none when ``dt`` <= 0; ``accel`` as in ``predict_kernel``), then the gated gyro
    update ``z = yaw_rate + bias``.

    ``y`` (shape (1,)) receives the residual; ``r`` is the gyro's noise (its model is ``H_GYRO``).
    """
    if dt > 0.0:
        predict_kernel(x, p, dt, q_rate, accel)
    y[0] = z_rps - x[_YAW_RATE] - x[_BIAS]
    return update_kernel(x, p, y, H_GYRO, r, gate, True, schmidt_state)


@numba.njit(cache=True)
def odometry_kernel(
    x: Array,
    p: Array,
    dt: float,
    q_rate: Array,
    accel: float,
    speed_mps: float,
    yaw_rate_rps: float,
    speed_variance: float,
    yaw_rate_variance: float,
    y: Array,
    h: Array,
    r: Array,
    gate: float,
    schmidt_state: int,
    scale_min: float,
    scale_max: float,
) -> tuple[float, bool]:
    """Predict over ``dt`` (s; none when ``dt`` <= 0; ``accel`` as in ``predict_kernel``), then the gated
    odometry update.

    With ``y`` of shape (2,): ``z = (scale * speed, yaw_rate)``, ``h`` (2, 7) gets its state-dependent
    speed row, ``r`` (2, 2) the two variances on its diagonal, and the scale is clamped to
    [``scale_min``, ``scale_max``] afterwards. With ``y`` of shape (1,): the yaw-rate row alone (``h`` its
    constant row, ``r`` (1, 1) gets ``yaw_rate_variance``; ``speed_*`` unused).
    """
    if dt > 0.0:
        predict_kernel(x, p, dt, q_rate, accel)
    if y.shape[0] == 1:
        y[0] = yaw_rate_rps - x[_YAW_RATE]
        r[0, 0] = yaw_rate_variance
        return update_kernel(x, p, y, h, r, gate, True, schmidt_state)
    y[0] = speed_mps - x[_SCALE] * x[_SPEED]
    y[1] = yaw_rate_rps - x[_YAW_RATE]
    h[0, _SPEED] = x[_SCALE]
    h[0, _SCALE] = x[_SPEED]
    r[0, 0] = speed_variance
    r[1, 1] = yaw_rate_variance
    nis, accepted = update_kernel(x, p, y, h, r, gate, True, schmidt_state)
    # Keep the scale physical: a linearised update at near-zero speed can push it anywhere (a NaN stays).
    if x[_SCALE] < scale_min:
        x[_SCALE] = scale_min
    elif x[_SCALE] > scale_max:
        x[_SCALE] = scale_max
    return nis, accepted
