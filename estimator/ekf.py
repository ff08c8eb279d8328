"""The rover EKF: planar pose, speed, yaw rate, gyro bias and odometry scale, gated on every update.

State ``x`` (shape (7,)), in order (``STATE_NAMES``)::

    x_m, y_m          position, local ENU metres
    yaw_rad           heading, radians CCW from east, wrapped to (-pi, pi]
    speed_mps         body forward speed over ground, m/s (negative when reversing)
    yaw_rate_rps      body yaw rate, rad/s
    gyro_bias_rps     additive bias of the z gyro, rad/s
    odom_scale        wheel surface speed / speed over ground (1 on firm ground, > 1 when the wheels slip)

Motion model: constant speed and yaw rate over ``dt``, position advanced along the mid-interval heading
(second-order accurate; dt is at most a few tens of ms between sensor samples); while the front end sets
an ``acceleration`` input (the IMU's, when the wheels slip along their travel), the speed changes at it.
Speed, yaw rate, gyro bias and odometry scale are random walks (intensities from ``EstimatorConfig``).

Measurement models: GPS ``z = (x, y)``; gyro ``z = yaw_rate + bias``; wheel odometry
``z = (odom_scale * speed, yaw_rate)`` (or the yaw-rate row alone when the speed is known to be bad);
heading ``z = yaw``. The scale is what makes dead reckoning on sand or mud honest: GPS teaches it while it is
there, and a GPS dropout then integrates ``odometry / scale`` instead of the raw wheel speed.

Why not ``filterpy.kalman.ExtendedKalmanFilter.update``: it applies every measurement unconditionally (the
gate must see ``S`` *before* the state changes), fixes ``dim_z`` at construction although our sensors have 1
or 2 dimensions, and deep-copies ``z`` on every call. The update here is the same EKF update with an
angle-wrapping residual, plus the gate, compiled with numba (``estimator.ekf_kernels``). It uses
``P - K S K^T`` (symmetric by construction) instead of filterpy's Joseph form because K is the optimal
gain, except while the odometry scale is only *considered* (Schmidt update: Joseph form). A test checks
both give filterpy's numbers; ``rover bench estimator`` times them against each other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from estimator.angles import wrap_angle
from estimator.chi_square import chi_square_quantile
from estimator.config import EstimatorConfig
from estimator.ekf_kernels import gyro_kernel, odometry_kernel, predict_kernel, update_kernel
from estimator.errors import EstimatorOperationError

STATE_NAMES: tuple[str, ...] = (
    "x_m",
    "y_m",
    "yaw_rad",
    "speed_mps",
    "yaw_rate_rps",
    "gyro_bias_rps",
    "odom_scale",
)
X, Y, YAW, SPEED, YAW_RATE, BIAS, SCALE = range(7)
DIM_X = 7

# Prior on the states nobody measured yet at initialisation: a rover starting up is nearly still.
_INITIAL_SPEED_STD_MPS = 1.0
_INITIAL_YAW_RATE_STD_RPS = 0.5
_INITIAL_BIAS_STD_RPS = 0.05
# The scale is a ratio of speeds: outside these the wheels are not rolling on the ground at all (stuck,
# airborne) and the stuck detector in the front end, not the scale, has to deal with it.
_SCALE_MIN, _SCALE_MAX = 0.7, 2.0

Array = NDArray[np.float64]


def _rows(*selected: int) -> Array:
    """A constant measurement matrix picking the given states."""
    h = np.zeros((len(selected), DIM_X))
    for row, column in enumerate(selected):
        h[row, column] = 1.0
    return h


_H_POSITION = _rows(X, Y)
_H_HEADING = _rows(YAW)
_H_ODOMETRY_YAW_RATE = _rows(YAW_RATE)


# A NamedTuple, immutable like a frozen dataclass but cheaper to build (two or three per control tick:
# the dataclass's __init__, an object.__setattr__ per field, was a measurable share of the tick).
class Innovation(NamedTuple):
    """One measurement update.

    Attributes
    ----------
    sensor : str
        "gps", "gyro", "odometry" or "heading".
    residual : tuple of float
        z - h(x) in measurement units (angles wrapped), before the update.
    nis : float
        Normalised innovation squared, y^T S^-1 y (dimensionless; chi-square with dim(z) dof if consistent).
    accepted : bool
        False when the gate refused the measurement; the state was then left untouched.
    """

    sensor: str
    residual: tuple[float, ...]
    nis: float
    accepted: bool


@dataclass(frozen=True, eq=False)
class Snapshot:
    """The filter at one instant, to go back to when a delayed measurement arrives (copies)."""

    t_ns: int
    x: Array
    p: Array
    acceleration: float = 0.0


class RoverEkf:
    """Extended Kalman filter for a skid-steer rover in the plane.

    Parameters
    ----------
    config : EstimatorConfig
        Process noise, default sensor noise and the gate probability. Read once here.
    """

    def __init__(self, config: EstimatorConfig) -> None:
        self._config = config
        self._x: Array = np.zeros(DIM_X)
        self._x[SCALE] = 1.0
        self._p: Array = np.eye(DIM_X)
        self._t_ns: int | None = None
        # Counts changes of x, P or the time (``revision``): a reader can tell the estimate is unchanged.
        self._revision = 0
        # Process noise intensities (per second) of the random walks, in the order of the kernels' WALK_STATES
        # (speed, yaw rate, gyro bias, odometry scale).
        self._q_rate: Array = np.array(
            [
                config.accel_process_noise**2,
                config.yaw_accel_process_noise**2,
                config.gyro_bias_walk**2,
                config.odom_scale_walk**2,
            ]
        )
        # Gate thresholds computed once per measurement dimension.
        self._gate = {dim: chi_square_quantile(config.gate_probability, dim) for dim in (1, 2)}
        self._r_gyro: Array = np.array([[config.gyro_noise_rps**2]])
        self._scale_learning = True
        # The measured body acceleration (m/s^2) every predict applies to the speed; 0 (the usual case): the
        # constant-speed model. The front end sets it while the wheels' speed cannot be trusted to follow
        # the body's (``estimator.longitudinal_slip``).
        self.acceleration = 0.0
        self._h_odometry: Array = _rows(SPEED, YAW_RATE)  # reused; its speed row depends on the state
        # Residual and noise buffers, filled in place per update: building small arrays anew cost more
        # than the update's arithmetic. The kernel reads them only during the call (``_update``).
        self._y1: Array = np.zeros(1)
        self._y2: Array = np.zeros(2)
        self._r1: Array = np.zeros((1, 1))
        self._r2: Array = np.zeros((2, 2))  # only the diagonal is ever set

    # --- state access --------------------------------------------------------------------------
    @property
    def initialised(self) -> bool:
        return self._t_ns is not None

    @property
    def t_ns(self) -> int:
        """Time of the current estimate, ns."""
        # The check inline (read several times per sample): _require_time only to raise.
        return self._t_ns if self._t_ns is not None else self._require_time()

    @property
    def revision(self) -> int:
        """A number that changes whenever the state, covariance or time may have changed: two equal
        revisions mean the same estimate (``Estimator.pose`` reuses its last answer on it)."""
        return self._revision

    @property
    def x(self) -> Array:
        """A copy of the state, shape (7,)."""
        return self._x.copy()

    @property
    def covariance(self) -> Array:
        """A copy of the state covariance, shape (7, 7), units of the state squared."""
        return self._p.copy()

    def state(self, index: int) -> float:
        """One state value without copying the vector."""
        return self._x.item(index)  # a Python float straight away, not a numpy scalar then float()

    def state_values(self) -> list[float]:
        """The state as Python floats, in ``STATE_NAMES`` order (one C call, not one per value)."""
        return self._x.tolist()

    def variance(self, index: int) -> float:
        """One diagonal entry of the covariance without copying it."""
        return float(self._p[index, index])

    def position_std_m(self) -> float:
        """Std (m) of the position along its worst direction."""
        return position_std_m(self._p)

    def snapshot(self) -> Snapshot:
        return Snapshot(self._require_time(), self._x.copy(), self._p.copy(), self.acceleration)

    def restore(self, snapshot: Snapshot) -> None:
        """Go back to a snapshot taken earlier (the buffer-and-re-fuse path for delayed measurements)."""
        self._x = snapshot.x.copy()
        self._p = snapshot.p.copy()
        self._t_ns = snapshot.t_ns
        self.acceleration = snapshot.acceleration
        self._revision += 1

    # --- set-up --------------------------------------------------------------------------------
    def initialise(
        self, x_m: float, y_m: float, yaw_rad: float, t_ns: int, position_std_m: float, yaw_std_rad: float
    ) -> None:
        """Start (or restart) the filter at a position and heading; speed and yaw rate start at zero."""
        _check_finite("initialise", x_m=x_m, y_m=y_m, yaw_rad=yaw_rad)
        _check_std("initialise", position_std_m=position_std_m, yaw_std_rad=yaw_std_rad)
        self._x[:] = (x_m, y_m, wrap_angle(yaw_rad), 0.0, 0.0, 0.0, 1.0)
        self._p[:] = np.diag(
            [
                position_std_m**2,
                position_std_m**2,
                yaw_std_rad**2,
                _INITIAL_SPEED_STD_MPS**2,
                _INITIAL_YAW_RATE_STD_RPS**2,
                _INITIAL_BIAS_STD_RPS**2,
                self._config.odom_scale_initial_std**2,
            ]
        )
        self._t_ns = t_ns
        self._revision += 1

    def reset_heading(self, yaw_rad: float, yaw_std_rad: float) -> None:
        """Replace the heading by an independent estimate, dropping its correlations with the rest."""
        self._require_time()
        _check_finite("reset_heading", yaw_rad=yaw_rad)
        _check_std("reset_heading", yaw_std_rad=yaw_std_rad)
        self._x[YAW] = wrap_angle(yaw_rad)
        self._p[YAW, :] = 0.0
        self._p[:, YAW] = 0.0
        self._p[YAW, YAW] = yaw_std_rad**2
        self._revision += 1

    def reset_position(self, x_m: float, y_m: float, position_std_m: float) -> None:
        """Re-anchor the position (e.g. after GPS was gated out too long), dropping its correlations."""
        self._require_time()
        _check_finite("reset_position", x_m=x_m, y_m=y_m)
        _check_std("reset_position", position_std_m=position_std_m)
        self._x[X], self._x[Y] = x_m, y_m
        self._p[(X, Y), :] = 0.0
        self._p[:, (X, Y)] = 0.0
        self._p[X, X] = self._p[Y, Y] = position_std_m**2
        self._revision += 1

    def reset_speed(self, speed_mps: float, speed_std_mps: float) -> None:
        """Replace the speed by an independent estimate (the IMU's, through a wheel skid), dropping its
        correlations with the rest."""
        self._require_time()
        _check_finite("reset_speed", speed_mps=speed_mps)
        _check_std("reset_speed", speed_std_mps=speed_std_mps)
        self._x[SPEED] = speed_mps
        self._p[SPEED, :] = 0.0
        self._p[:, SPEED] = 0.0
        self._p[SPEED, SPEED] = speed_std_mps**2
        self._revision += 1

    @property
    def scale_learning(self) -> bool:
        return self._scale_learning

    def learn_scale(self, on: bool) -> None:
        """Let updates correct the odometry scale (on) or only *consider* it (off).

        The scale is observable only against an absolute speed: GPS track with a known heading. Without
        one (heading still unknown, GPS lost, wheels spinning) the bilinear ``scale * speed`` model lets
        an EKF wander along ``scale * speed = odometry`` and dead reckoning then drifts by tens of percent.
        Off, the scale is a Schmidt "consider" state: its uncertainty still widens P for the other states,
        but updates leave its value and its variance alone.
        """
        self._scale_learning = on

    def inflate(self, index: int, std: float) -> None:
        """Add ``std**2`` to one state's variance: it is known to be worse than the filter thinks."""
        self._require_time()
        _check_std("inflate", std=std)
        self._p[index, index] += std**2
        self._revision += 1

    # --- prediction ----------------------------------------------------------------------------
    def predict(self, t_ns: int) -> None:
        """Advance the estimate to ``t_ns``; a time at or before the current one changes nothing."""
        dt_ns = t_ns - (self._t_ns if self._t_ns is not None else self._require_time())
        if dt_ns <= 0:
            return
        predict_kernel(self._x, self._p, dt_ns * 1e-9, self._q_rate, self.acceleration)
        self._t_ns = t_ns
        self._revision += 1

    def predicted(self, t_ns: int) -> tuple[Array, Array]:
        """State and covariance extrapolated to ``t_ns`` without changing the filter (copies)."""
        saved_x, saved_p, saved_t = self._x.copy(), self._p.copy(), self._t_ns
        try:
            self.predict(t_ns)
            return self._x.copy(), self._p.copy()
        finally:
            # The revision stays advanced: a reader recomputes from the restored state, so a restore
            # that missed something would show rather than hide behind an unchanged revision.
            self._x, self._p, self._t_ns = saved_x, saved_p, saved_t

    def _seconds_to(self, t_ns: int | None) -> float:
        """Before an update at ``t_ns`` (None: at the filter's time): the seconds to predict over (0.0 for
        none, as ``predict`` for a time not after the current one), with the time and revision advanced."""
        now_ns = self._t_ns if self._t_ns is not None else self._require_time()
        if t_ns is None or t_ns <= now_ns:
            return 0.0
        self._t_ns = t_ns
        self._revision += 1
        return (t_ns - now_ns) * 1e-9

    # --- measurement updates -------------------------------------------------------------------
    def update_position(self, x_m: float, y_m: float, std_m: float, *, gated: bool = True) -> Innovation:
        """GPS position in ENU metres with a per-axis std (m).

        ``gated=False`` skips the gate: for when the covariance is known not to be trustworthy (heading
        still unknown), so the gate would refuse good fixes.
        """
        # The checks' common case in one expression; the check functions name what was wrong.
        if not (math.isfinite(x_m) and math.isfinite(y_m)):
            _check_finite("update_position", x_m=x_m, y_m=y_m)
        if not 0.0 < std_m < math.inf:
            _check_std("update_position", std_m=std_m)
        x = self._x.tolist()  # Python floats: cheaper arithmetic than numpy scalars
        y = self._y2
        y[0], y[1] = x_m - x[X], y_m - x[Y]
        variance = std_m * std_m
        r = self._r2
        r[0, 0] = r[1, 1] = variance
        return self._update("gps", y, _H_POSITION, r, gated=gated)

    def update_gyro(self, z_rps: float, *, t_ns: int | None = None) -> Innovation:
        """Body z gyro, rad/s: measures yaw rate + bias.

        With ``t_ns``, first predicts to it (as ``predict``) in the same compiled call: a sample's predict
        and update, the same arithmetic as the two calls.
        """
        if not math.isfinite(z_rps):
            _check_finite("update_gyro", z_rps=z_rps)
        dt = self._seconds_to(t_ns)
        y = self._y1
        nis, accepted = gyro_kernel(
            self._x, self._p, dt, self._q_rate, self.acceleration, z_rps, y, self._r_gyro,
            self._gate[1], -1 if self._scale_learning else SCALE,
        )  # fmt: skip
        self._revision += 1
        return Innovation("gyro", (y.item(0),), nis, accepted)

    def update_odometry(
        self,
        speed_mps: float,
        yaw_rate_rps: float,
        speed_std_mps: float,
        yaw_rate_std_rps: float,
        *,
        use_speed: bool = True,
        t_ns: int | None = None,
    ) -> Innovation:
        """Wheel odometry: mean wheel surface speed (m/s) and yaw rate (rad/s) with their std.

        The speed row measures ``odom_scale * speed``. ``use_speed=False`` fuses the yaw rate alone (the
        wheels are spinning in place: their speed says nothing about the ground); the residual then has
        one entry. With ``t_ns``, first predicts to it (as ``predict``) in the same compiled call.
        """
        if not (math.isfinite(speed_mps) and math.isfinite(yaw_rate_rps)):
            _check_finite("update_odometry", speed_mps=speed_mps, yaw_rate_rps=yaw_rate_rps)
        if not (0.0 < speed_std_mps < math.inf and 0.0 < yaw_rate_std_rps < math.inf):
            _check_std("update_odometry", speed_std_mps=speed_std_mps, yaw_rate_std_rps=yaw_rate_std_rps)
        dt = self._seconds_to(t_ns)
        # The kernel fills the residual, the state-dependent speed row of H and the noise in place.
        if use_speed:
            y, h, r = self._y2, self._h_odometry, self._r2
        else:
            y, h, r = self._y1, _H_ODOMETRY_YAW_RATE, self._r1
        nis, accepted = odometry_kernel(
            self._x, self._p, dt, self._q_rate, self.acceleration, speed_mps, yaw_rate_rps, speed_std_mps**2,
            yaw_rate_std_rps**2, y, h, r, self._gate[len(y)], -1 if self._scale_learning else SCALE,
            _SCALE_MIN, _SCALE_MAX,
        )  # fmt: skip
        self._revision += 1
        return Innovation("odometry", tuple(y.tolist()), nis, accepted)

    def update_heading(self, yaw_rad: float, std_rad: float) -> Innovation:
        """An absolute heading (compass, dual-antenna GPS), radians CCW from east."""
        if not math.isfinite(yaw_rad):
            _check_finite("update_heading", yaw_rad=yaw_rad)
        if not 0.0 < std_rad < math.inf:
            _check_std("update_heading", std_rad=std_rad)
        y = self._y1
        y[0] = wrap_angle(yaw_rad - self._x[YAW])
        r = self._r1
        r[0, 0] = std_rad**2
        return self._update("heading", y, _H_HEADING, r)

    def _update(self, sensor: str, y: Array, h: Array, r: Array, *, gated: bool = True) -> Innovation:
        """Gate, then the EKF update (compiled: ``ekf_kernels.update_kernel``); ``y`` is z - h(x)."""
        if self._t_ns is None:
            self._require_time()
        schmidt = -1 if self._scale_learning else SCALE
        nis, accepted = update_kernel(self._x, self._p, y, h, r, self._gate[len(y)], gated, schmidt)
        self._revision += 1
        return Innovation(sensor, tuple(y.tolist()), float(nis), bool(accepted))

    def _require_time(self) -> int:
        if self._t_ns is None:
            raise EstimatorOperationError(
                "the EKF is not initialised yet; call initialise() (the estimator does on the first GPS fix)"
            )
        return self._t_ns


def position_std_m(covariance: Array) -> float:
    """Sqrt of the largest eigenvalue of the 2x2 position block of a state covariance, metres."""
    # item(): Python floats, not numpy scalars; the same IEEE arithmetic (** is libm's pow for both).
    a, b, c = covariance.item(X, X), covariance.item(X, Y), covariance.item(Y, Y)
    # Closed-form eigenvalue of a symmetric 2x2: cheaper than eigvalsh in a hot loop.
    largest = 0.5 * (a + c) + math.sqrt(max(0.25 * (a - c) ** 2 + b * b, 0.0))
    return math.sqrt(max(float(largest), 0.0))


def _check_finite(where: str, **values: float) -> None:
    for name, value in values.items():
        if not math.isfinite(value):
            raise EstimatorOperationError(f"{where}: {name} must be finite, got {value}")


def _check_std(where: str, **values: float) -> None:
    for name, value in values.items():
        if not math.isfinite(value) or value <= 0.0:
            raise EstimatorOperationError(f"{where}: {name} must be a finite std > 0, got {value}")


def load_kernels(config: EstimatorConfig) -> None:
    """Run a throwaway filter through a predict and each kind of update, so the compiled kernels are
    loaded from numba's cache (or compiled, on a machine's first run) now: a real-time process calls this
    before its loop, where a first-use compile would stall the control tick for seconds."""
    ekf = RoverEkf(config)
    ekf.initialise(0.0, 0.0, 0.0, 0, 1.0, 1.0)
    ekf.predict(10_000_000)
    ekf.update_position(0.1, 0.1, 1.0, gated=False)
    ekf.update_gyro(0.0, t_ns=20_000_000)
    ekf.update_odometry(0.0, 0.0, 0.1, 0.1, t_ns=30_000_000)
