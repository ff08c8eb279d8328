"""The benchmark peer: the same rover model on filterpy's ``ExtendedKalmanFilter``, used the plain way.

Same state, motion model, Jacobians and noise as ``estimator.ekf.RoverEkf`` (no gate, no odometry scale
clamp), so ``rover bench estimator`` compares the arithmetic, not the features. filterpy's predict is
linear (``x = F x``), so ``predict_x`` is overridden with the rover's motion, as its documentation
suggests for nonlinear process models.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter
from numpy.typing import NDArray

from estimator.angles import wrap_angle
from estimator.config import EstimatorConfig
from estimator.ekf import BIAS, DIM_X, SCALE, SPEED, YAW, YAW_RATE, X, Y

Array = NDArray[np.float64]

_H_POSITION = np.zeros((2, DIM_X))
_H_POSITION[0, X] = _H_POSITION[1, Y] = 1.0
_H_GYRO = np.zeros((1, DIM_X))
_H_GYRO[0, YAW_RATE] = _H_GYRO[0, BIAS] = 1.0


def _residual(a: Any, b: Any) -> Any:
    return np.subtract(a, b)


class FilterpyRoverEkf(ExtendedKalmanFilter):  # filterpy is untyped (Any) for mypy
    """``RoverEkf``'s model on filterpy: ``step(dt)`` then ``update_gyro`` / ``update_odometry`` / ..."""

    def __init__(self, config: EstimatorConfig, dt: float) -> None:
        super().__init__(dim_x=DIM_X, dim_z=2)
        self.x = np.zeros(DIM_X)
        self.x[SCALE] = 1.0
        self.P = np.diag([0.25, 0.25, 0.01, 1.0, 0.25, 0.0025, 0.0025])
        self._dt = dt
        q = np.zeros(DIM_X)
        q[[SPEED, YAW_RATE, BIAS, SCALE]] = [
            config.accel_process_noise**2,
            config.yaw_accel_process_noise**2,
            config.gyro_bias_walk**2,
            config.odom_scale_walk**2,
        ]
        self.Q = np.diag(q * dt)
        self._r_gyro = np.array([[config.gyro_noise_rps**2]])

    def predict_x(self, u: Any = 0) -> None:
        dt = self._dt
        x = self.x
        v, w = x[SPEED], x[YAW_RATE]
        heading = x[YAW] + 0.5 * w * dt
        cos_h, sin_h = math.cos(heading), math.sin(heading)
        step = v * dt
        f = np.eye(DIM_X)
        f[X, YAW] = -step * sin_h
        f[X, SPEED] = dt * cos_h
        f[X, YAW_RATE] = -step * sin_h * 0.5 * dt
        f[Y, YAW] = step * cos_h
        f[Y, SPEED] = dt * sin_h
        f[Y, YAW_RATE] = step * cos_h * 0.5 * dt
        f[YAW, YAW_RATE] = dt
        self.F = f
        x[X] += step * cos_h
        x[Y] += step * sin_h
        x[YAW] = wrap_angle(x[YAW] + w * dt)

    def update_position(self, x_m: float, y_m: float, std_m: float) -> None:
        self.update(
            np.array([x_m, y_m]),
            lambda _x: _H_POSITION,
            lambda x: x[[X, Y]],
            R=np.eye(2) * std_m**2,
            residual=_residual,
        )

    def update_gyro(self, z_rps: float) -> None:
        self.update(
            np.array([z_rps]),
            lambda _x: _H_GYRO,
            lambda x: np.array([x[YAW_RATE] + x[BIAS]]),
            R=self._r_gyro,
            residual=_residual,
        )

    def update_odometry(self, speed: float, yaw_rate: float, speed_std: float, yaw_rate_std: float) -> None:
        def jacobian(x: Array) -> Array:
            h = np.zeros((2, DIM_X))
            h[0, SPEED], h[0, SCALE], h[1, YAW_RATE] = x[SCALE], x[SPEED], 1.0
            return h

        self.update(
            np.array([speed, yaw_rate]),
            jacobian,
            lambda x: np.array([x[SCALE] * x[SPEED], x[YAW_RATE]]),
            R=np.diag([speed_std**2, yaw_rate_std**2]),
            residual=_residual,
        )
