"""Estimator settings: a frozen dataclass, validated when built, read strictly from ``[estimator]``."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from estimator.errors import EstimatorSetupError
from estimator.geodesy import Datum
from logs.settings import Table

# Settings that must be strictly positive (noise levels and lengths): a zero would make a matrix singular.
_POSITIVE = (
    "gps_noise_m",
    "gyro_noise_rps",
    "odom_speed_noise_mps",
    "odom_yaw_rate_noise_rps",
    "accel_process_noise",
    "yaw_accel_process_noise",
    "gyro_bias_walk",
    "odom_scale_walk",
    "odom_scale_initial_std",
    "track_m",
    "skid_factor",
    "healthy_position_std_m",
    "heading_init_distance_m",
    "slip_threshold_rps",
    "healthy_heading_std_deg",
    "gps_reset_after_s",
    "gps_timeout_s",
    "stuck_window_s",
    "stuck_min_distance_m",
    "odom_transient_accel_mps2",
    "odom_settle_s",
    "long_slip_window_s",
    "long_slip_max_s",
)
# Settings that may be zero but not negative.
_NON_NEGATIVE = ("gps_latency_s", "odom_yaw_rate_relative_noise", "long_slip_threshold_mps")


@dataclass(frozen=True)
class EstimatorConfig:
    """Noise levels, gate and vehicle geometry of the rover EKF.

    Attributes
    ----------
    gps_noise_m : float
        Horizontal GPS std (m, per axis) used when a fix carries no ``eph``, and the floor under ``eph``.
    gyro_noise_rps : float
        Gyro z std, rad/s.
    odom_speed_noise_mps, odom_yaw_rate_noise_rps : float
        Wheel odometry std of body speed (m/s) and yaw rate (rad/s) when the wheels do not slip.
    odom_yaw_rate_relative_noise : float
        Further odometry yaw-rate std as a share of the yaw rate: a skid-steer's effective skid factor
        changes with ground and load, so its turn rate from the wheels is uncertain in proportion. Without
        it, the gyro bias state soaks up the skid error of every turn.
    accel_process_noise : float
        Random walk on speed, m/s^2 (std of the white acceleration driving it).
    yaw_accel_process_noise : float
        Random walk on yaw rate, rad/s^2.
    gyro_bias_walk : float
        Random walk on the gyro bias, rad/s per sqrt(s).
    odom_scale_walk : float
        Random walk on the odometry scale (wheel speed / ground speed), 1 per sqrt(s): how fast the
        filter lets the ground change from firm to slippery.
    odom_scale_initial_std : float
        Prior std of the odometry scale at start (1 sigma, as a ratio): how well the wheel radius is
        calibrated for the ground the rover starts on. 0.03 suits a radius measured to a few percent on firm
        ground: a few seconds of noisy GPS cannot then talk the scale 5 % off (which a GPS dropout right
        after would integrate as 5 % of distance); the scale still learns loose ground's 10-15 % slip, over
        tens of seconds of GPS. Raise it when the rover starts on known-soft ground.
    gate_probability : float
        Chi-square gate on every update: a measurement whose NIS exceeds the chi-square quantile ``p`` of
        its dimension (``estimator.chi_square``) is rejected.
    track_m, skid_factor : float
        Skid-steer odometry: yaw rate = (v_right - v_left) / (track_m * skid_factor).
    healthy_position_std_m : float
        The estimate is healthy while the largest position std (m) stays below this.
    healthy_heading_std_deg : float
        ... and the heading std (degrees) below this.
    heading_init_distance_m : float
        With no heading given, GPS displacement (m) the rover must cover before yaw is taken from its track.
    slip_threshold_rps : float
        |odometry yaw rate - gyro yaw rate| (rad/s) above which odometry noise is inflated (wheels slipping).
    gps_reset_after_s : float
        GPS gated out for this long without a single accepted fix in between (a persistent offset, not a
        glitch) makes the filter believe GPS and re-anchor its position, once, with a logged warning.
    gps_timeout_s : float
        Health flag ``gps_fresh`` turns False when the last accepted fix is older than this (s).
    gps_latency_s : float
        Age of a fix when it reaches us (s): it is fused at ``t - latency`` by going back to the filter
        state of that instant and re-fusing the IMU and wheel samples since (0: fused on arrival).
    stuck_window_s, stuck_min_distance_m : float
        Over every window of this length (s) with at least this much odometry travel (m), GPS travel is
        compared with odometry travel: wheels that turn while GPS stands still are spinning in place,
        and their speed is then left out until the two agree again.
    odom_transient_accel_mps2, odom_settle_s : float
        While the mean wheel speed changes faster than this (m/s^2), and for ``odom_settle_s`` after, the
        wheels lead or lag the body (transient slip): the odometry scale is not learnt
        (``estimator.transient``).
    long_slip_threshold_mps, long_slip_window_s, long_slip_max_s : float
        Wheels slipping along their travel (a braking skid, launch spin; ``estimator.longitudinal_slip``):
        when, over ``long_slip_window_s``, the wheel speed changed by more than ``long_slip_threshold_mps``
        (m/s) more or less than the body did by the IMU (its longitudinal specific force less gravity along
        the AHRS pitch), and the wheels' own change was larger than the threshold too, on two samples in a
        row, the speed is carried by the IMU's acceleration and the wheels' speed left out, until the wheels
        agree with the estimate again within half the threshold, for at most ``long_slip_max_s``. Needs AHRS
        attitudes (the pitch); 0 for the threshold turns it off. Counters: ``odometry_long_slip_on`` /
        ``_off`` (slips begun and ended), ``odometry_long_slip`` (odometry samples in one),
        ``odometry_long_slip_no_pitch`` (ended for want of a pitch), ``imu_accel_knock`` (IMU samples beyond
        1 g left out).
    datum_lat_deg, datum_lon_deg, datum_alt_m : float | None
        ENU origin; if absent the first good GPS fix sets it.
    """

    gps_noise_m: float = 0.5
    gyro_noise_rps: float = 0.01
    odom_speed_noise_mps: float = 0.05
    odom_yaw_rate_noise_rps: float = 0.05
    odom_yaw_rate_relative_noise: float = 0.3
    accel_process_noise: float = 0.5
    yaw_accel_process_noise: float = 1.0
    gyro_bias_walk: float = 1e-4
    odom_scale_walk: float = 0.002
    odom_scale_initial_std: float = 0.03
    gate_probability: float = 0.9995
    track_m: float = 0.55
    skid_factor: float = 1.6
    healthy_position_std_m: float = 2.0
    healthy_heading_std_deg: float = 10.0
    heading_init_distance_m: float = 5.0
    slip_threshold_rps: float = 0.15
    gps_reset_after_s: float = 10.0
    gps_timeout_s: float = 2.0
    gps_latency_s: float = 0.0
    stuck_window_s: float = 4.0
    stuck_min_distance_m: float = 1.0
    odom_transient_accel_mps2: float = 1.0
    odom_settle_s: float = 1.0
    long_slip_threshold_mps: float = 0.15
    long_slip_window_s: float = 0.25
    long_slip_max_s: float = 1.0
    datum_lat_deg: float | None = None
    datum_lon_deg: float | None = None
    datum_alt_m: float | None = None

    def __post_init__(self) -> None:
        for name in _POSITIVE:
            value = getattr(self, name)
            if not math.isfinite(value) or value <= 0.0:
                raise EstimatorSetupError(name, f"must be a finite number > 0, got {value}")
        for name in _NON_NEGATIVE:
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0.0:
                raise EstimatorSetupError(name, f"must be a finite number >= 0, got {value}")
        for name in ("long_slip_window_s", "long_slip_max_s"):
            if getattr(self, name) > 5.0:
                raise EstimatorSetupError(
                    name, f"must be at most 5 s (a skid lasts tenths), got {getattr(self, name)}"
                )
        if not 0.5 <= self.gate_probability < 1.0:
            raise EstimatorSetupError(
                "gate_probability", f"must be in [0.5, 1) (e.g. 0.9995), got {self.gate_probability}"
            )
        if (self.datum_lat_deg is None) != (self.datum_lon_deg is None):
            raise EstimatorSetupError("datum_lat_deg", "give both datum_lat_deg and datum_lon_deg or neither")
        if self.datum_lat_deg is None and self.datum_alt_m is not None:
            raise EstimatorSetupError("datum_alt_m", "datum_alt_m needs datum_lat_deg and datum_lon_deg")
        _ = self.datum  # validates the datum values

    @property
    def datum(self) -> Datum | None:
        """The configured ENU origin, or None when the first good fix should set it."""
        if self.datum_lat_deg is None or self.datum_lon_deg is None:
            return None
        return Datum(self.datum_lat_deg, self.datum_lon_deg, self.datum_alt_m or 0.0)

    @classmethod
    def from_table(cls, table: Table) -> EstimatorConfig:
        """Read the ``[estimator]`` table; unknown keys and bad values raise ``ConfigError`` naming it."""
        values: dict[str, float | None] = {}
        for f in fields(cls):
            default = f.default
            if default is None:
                values[f.name] = table.number(f.name) if table.has(f.name) else None
            else:
                assert isinstance(default, float)
                values[f.name] = table.number(f.name, default)
        table.finish()
        try:
            return cls(**values)  # type: ignore[arg-type]
        except EstimatorSetupError as err:
            raise table.error(err.field, err.problem) from err
