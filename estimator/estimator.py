"""The measurement-level front end of the EKF: raw GPS / IMU / wheel samples in, pose and innovations out.

It checks every sample (bad ones are counted by reason and logged, never raised), owns the ENU datum,
initialises the filter on the first good fix, learns the heading from motion when nobody gave one, turns
wheel speeds into body motion, and publishes one ``estimator/innovations`` message per update.
"""

from __future__ import annotations

import logging
import math
from collections import Counter

from estimator.angles import wrap_angle
from estimator.config import EstimatorConfig
from estimator.ekf import BIAS, SPEED, YAW, YAW_RATE, Innovation, RoverEkf, position_std_m
from estimator.errors import EstimatorSetupError
from estimator.geodesy import Datum, to_enu
from estimator.heading_bootstrap import HeadingBootstrap
from estimator.pose import PoseEstimate, pose_message
from logs.clock import Clock
from logs.sink import MessageSink
from logs.topics import ESTIMATOR_INNOVATIONS, ESTIMATOR_POSE, stamp

logger = logging.getLogger(__name__)

# MAVLink GPS_FIX_TYPE: 3 = 3D fix and better (DGPS, RTK float/fixed). A 2D fix has no usable altitude
# and is often a receiver still settling, so it is refused rather than half-trusted.
MIN_FIX_TYPE = 3
# Heading std while unknown: any direction is as likely as any other.
UNKNOWN_HEADING_STD_RAD = math.pi
# A gyro sample older than this is no evidence about the wheels' current yaw rate.
_GYRO_FRESH_NS = 100_000_000
# Log the first rejection of each kind, then every n-th, so a 50 Hz fault cannot flood the log.
_LOG_EVERY = 100


class Estimator:
    """Fuses GPS, gyro and wheel odometry into a planar pose.

    Parameters
    ----------
    config : EstimatorConfig
        Noise levels, gate, vehicle geometry and optional datum.
    clock : Clock
        Source of ``log_time`` for published messages (measurement times come with each sample).
    sink : MessageSink
        Receives ``estimator/innovations`` and ``estimator/pose``.
    """

    def __init__(self, config: EstimatorConfig, clock: Clock, sink: MessageSink) -> None:
        self._config = config
        self._clock = clock
        self._sink = sink
        self._ekf = RoverEkf(config)
        self._datum: Datum | None = config.datum
        self._counters: Counter[str] = Counter()
        self._bootstrap = HeadingBootstrap(config.heading_init_distance_m)
        self._initial_heading: tuple[float, float] | None = None
        self._heading_known = False
        self._odometry_seen = False
        self._gps_rejected_in_row = 0
        self._last_gyro: tuple[int, float] | None = None  # (t_ns, raw gyro z rad/s)

    # --- read-only views -----------------------------------------------------------------------
    @property
    def datum(self) -> Datum | None:
        return self._datum

    @property
    def counters(self) -> dict[str, int]:
        """Accepted / rejected / ignored samples by reason (a copy)."""
        return dict(self._counters)

    @property
    def initialised(self) -> bool:
        return self._ekf.initialised

    @property
    def heading_known(self) -> bool:
        return self._heading_known

    # --- heading -------------------------------------------------------------------------------
    def set_initial_heading(self, yaw_rad: float, std_rad: float) -> None:
        """Give the heading (rad CCW from east, std rad), e.g. from a known start pose or a compass.

        Before the first fix it is used to initialise the filter; afterwards it replaces the heading.
        """
        if not math.isfinite(yaw_rad) or not math.isfinite(std_rad) or std_rad <= 0.0:
            raise EstimatorSetupError(
                "initial_heading", f"need a finite yaw and a std > 0, got yaw={yaw_rad}, std={std_rad}"
            )
        if self._ekf.initialised:
            self._ekf.reset_heading(yaw_rad, std_rad)
        else:
            self._initial_heading = (wrap_angle(yaw_rad), std_rad)
        self._heading_known = True

    # --- sensors -------------------------------------------------------------------------------
    def on_gps(
        self,
        t_ns: int,
        lat_deg: float,
        lon_deg: float,
        alt_m: float,
        fix_type: int,
        eph_m: float | None,
        satellites: int,
    ) -> None:
        """A GPS fix (WGS84 degrees, metres). ``eph_m`` is the horizontal std (m) or None if unknown.

        ``satellites`` is informational; the receiver's ``fix_type`` already says whether enough were used.
        """
        if fix_type < MIN_FIX_TYPE:
            self._reject("gps_no_fix", f"fix_type {fix_type} < {MIN_FIX_TYPE} (3D), {satellites} satellites")
            return
        if not (math.isfinite(lat_deg) and math.isfinite(lon_deg) and math.isfinite(alt_m)):
            self._reject("gps_not_finite", f"lat={lat_deg}, lon={lon_deg}, alt={alt_m}")
            return
        if not (-90.0 <= lat_deg <= 90.0 and -180.0 <= lon_deg <= 180.0):
            self._reject("gps_out_of_range", f"lat={lat_deg}, lon={lon_deg} outside [-90, 90] x [-180, 180]")
            return
        if eph_m is not None and (not math.isfinite(eph_m) or eph_m < 0.0):
            self._reject("gps_bad_eph", f"eph_m={eph_m} is not a finite std >= 0")
            return
        if self._datum is None:
            try:
                self._datum = Datum(lat_deg, lon_deg, alt_m)
            except EstimatorSetupError as err:
                self._reject("gps_out_of_range", f"cannot use this fix as datum: {err}")
                return
            logger.info("ENU datum set from the first good fix: %s", self._datum)
        east, north, _ = to_enu(self._datum, lat_deg, lon_deg, alt_m)
        std = max(eph_m if eph_m is not None else 0.0, self._config.gps_noise_m)

        if not self._ekf.initialised:
            self._initialise(t_ns, east, north, std)
            return
        self._advance(t_ns)
        # Until the heading is known the covariance rests on a linearisation that may be far off, so the
        # gate would throw away exactly the fixes that teach us the heading.
        innovation = self._ekf.update_position(east, north, std, gated=self._heading_known)
        self._publish_innovation(t_ns, innovation)
        if not self._heading_known:
            self._learn_heading(east, north, std)
        if innovation.accepted:
            self._gps_rejected_in_row = 0
            self._counters["gps_accepted"] += 1
            return
        self._gps_rejected_in_row += 1
        self._reject("gps_gated", f"NIS {innovation.nis:.1f}, residual {innovation.residual} m")
        if self._gps_rejected_in_row >= self._config.gps_reset_after_rejections:
            # Many fixes in a row disagree with us: more likely we drifted than that GPS is wrong for so long.
            self._ekf.reset_position(east, north, std)
            self._counters["gps_reset"] += 1
            logger.warning(
                "%d GPS fixes in a row were gated out; position re-anchored on GPS at (%.1f, %.1f) m",
                self._gps_rejected_in_row,
                east,
                north,
            )
            self._gps_rejected_in_row = 0

    def on_imu(self, t_ns: int, gyro_z_rps: float, accel_x: float, accel_y: float) -> None:
        """Body-frame IMU sample: gyro z (rad/s, CCW positive); accelerations (m/s^2) are not fused yet."""
        if not math.isfinite(gyro_z_rps):
            self._reject("imu_not_finite", f"gyro_z_rps={gyro_z_rps}")
            return
        self._last_gyro = (t_ns, gyro_z_rps)
        if not self._ekf.initialised:
            self._counters["imu_before_init"] += 1
            return
        self._advance(t_ns)
        innovation = self._ekf.update_gyro(gyro_z_rps)
        self._publish_innovation(t_ns, innovation)
        self._count(innovation, "gyro")

    def on_wheels(self, t_ns: int, left_speed_mps: float, right_speed_mps: float) -> None:
        """Mean left and right wheel surface speeds (m/s) -> skid-steer body speed and yaw rate."""
        if not (math.isfinite(left_speed_mps) and math.isfinite(right_speed_mps)):
            self._reject("wheels_not_finite", f"left={left_speed_mps}, right={right_speed_mps}")
            return
        if not self._ekf.initialised:
            self._counters["wheels_before_init"] += 1
            return
        speed = 0.5 * (left_speed_mps + right_speed_mps)
        yaw_rate = (right_speed_mps - left_speed_mps) / (self._config.track_m * self._config.skid_factor)
        speed_std, yaw_rate_std = self._odometry_noise(t_ns, yaw_rate)
        self._advance(t_ns)
        innovation = self._ekf.update_odometry(speed, yaw_rate, speed_std, yaw_rate_std)
        self._odometry_seen = True
        self._publish_innovation(t_ns, innovation)
        self._count(innovation, "odometry")

    # --- output --------------------------------------------------------------------------------
    def pose(self, t_ns: int | None = None) -> PoseEstimate | None:
        """The estimate, extrapolated to ``t_ns`` if later than the last sample; None before the first fix."""
        if not self._ekf.initialised:
            return None
        if t_ns is not None and t_ns > self._ekf.t_ns:
            x, p = self._ekf.predicted(t_ns)
        else:
            x, p, t_ns = self._ekf.x, self._ekf.covariance, self._ekf.t_ns
        std = position_std_m(p)
        return PoseEstimate(
            x=float(x[0]),
            y=float(x[1]),
            yaw=float(x[2]),
            speed=float(x[SPEED]),
            yaw_rate=float(x[YAW_RATE]),
            covariance=p,
            healthy=std < self._config.healthy_position_std_m,
            t_ns=t_ns,
            heading_known=self._heading_known,
            position_std_m=std,
        )

    def publish_pose(self, t_ns: int) -> bool:
        """Publish ``estimator/pose`` for ``t_ns``; returns False (nothing published) before the first fix."""
        pose = self.pose(t_ns)
        if pose is None:
            return False
        self._sink.publish(ESTIMATOR_POSE, self._clock.now_ns(), pose_message(pose))
        return True

    # --- internals -----------------------------------------------------------------------------
    def _initialise(self, t_ns: int, east: float, north: float, std: float) -> None:
        if self._initial_heading is not None:
            yaw, yaw_std = self._initial_heading
        else:
            yaw, yaw_std = 0.0, UNKNOWN_HEADING_STD_RAD
            self._bootstrap.on_fix(east, north, std, path_known=False)  # anchors the first chord
        self._ekf.initialise(east, north, yaw, t_ns, std, yaw_std)
        self._counters["gps_initialised"] += 1
        logger.info("estimator initialised at (%.2f, %.2f) m, heading known: %s", east, north, yaw_std < 1.0)

    def _advance(self, t_ns: int) -> None:
        """Predict to ``t_ns``, feeding the heading bootstrap the motion the filter believes in meanwhile."""
        dt_ns = t_ns - self._ekf.t_ns
        if dt_ns > 0 and not self._heading_known:
            dt = dt_ns * 1e-9
            self._bootstrap.add_motion(
                self._ekf.state(YAW_RATE) * dt, self._ekf.state(SPEED) * dt if self._odometry_seen else 0.0
            )
        self._ekf.predict(t_ns)

    def _learn_heading(self, east: float, north: float, std: float) -> None:
        guess = self._bootstrap.on_fix(east, north, std, path_known=self._odometry_seen)
        if guess is None:
            return
        self._heading_known = True
        # GPS updates have been teaching the filter its heading all along (through the position/yaw
        # covariance). If that estimate is already tighter than the chord and agrees with it, keep it: the
        # chord check only guards against the filter having settled on a wrong linearisation.
        filter_yaw = self._ekf.state(YAW)
        filter_std = math.sqrt(self._ekf.covariance[YAW, YAW])
        disagreement = abs(wrap_angle(filter_yaw - guess.yaw_rad))
        if filter_std < guess.std_rad and disagreement < 3.0 * math.hypot(filter_std, guess.std_rad):
            self._counters["heading_confirmed_by_motion"] += 1
            logger.info("motion confirms the filter heading %.3f rad (std %.3f)", filter_yaw, filter_std)
            return
        self._ekf.reset_heading(guess.yaw_rad, guess.std_rad)
        # The position was propagated along the wrong heading, and its covariance with it: restart it too.
        self._ekf.reset_position(east, north, std)
        self._counters["heading_from_motion"] += 1
        logger.info("heading learnt from motion: %.3f rad (std %.3f rad)", guess.yaw_rad, guess.std_rad)

    def _odometry_noise(self, t_ns: int, odom_yaw_rate: float) -> tuple[float, float]:
        """Odometry std (speed m/s, yaw rate rad/s), inflated when wheels and gyro disagree (slip).

        Skid-steer wheels slip all the time on turns and loose ground; when the odometry yaw rate departs
        from the bias-corrected gyro by more than the threshold, trust the wheels less in proportion.
        """
        speed_std = self._config.odom_speed_noise_mps
        yaw_rate_std = self._config.odom_yaw_rate_noise_rps
        if self._last_gyro is None or abs(t_ns - self._last_gyro[0]) > _GYRO_FRESH_NS:
            return speed_std, yaw_rate_std
        gyro_rate = self._last_gyro[1] - self._ekf.state(BIAS)
        mismatch = abs(odom_yaw_rate - gyro_rate)
        if mismatch <= self._config.slip_threshold_rps:
            return speed_std, yaw_rate_std
        self._counters["odometry_slip"] += 1
        factor = mismatch / self._config.slip_threshold_rps
        return speed_std * factor, max(yaw_rate_std * factor, mismatch)

    def _publish_innovation(self, t_ns: int, innovation: Innovation) -> None:
        message = {
            "timestamp": stamp(t_ns),
            "sensor": innovation.sensor,
            "innovation": list(innovation.residual),
            "nis": innovation.nis,
            "accepted": innovation.accepted,
        }
        self._sink.publish(ESTIMATOR_INNOVATIONS, self._clock.now_ns(), message)

    def _count(self, innovation: Innovation, sensor: str) -> None:
        if innovation.accepted:
            self._counters[f"{sensor}_accepted"] += 1
        else:
            self._reject(f"{sensor}_gated", f"NIS {innovation.nis:.1f}, residual {innovation.residual}")

    def _reject(self, reason: str, detail: str) -> None:
        self._counters[reason] += 1
        count = self._counters[reason]
        if count == 1 or count % _LOG_EVERY == 0:
            logger.warning("estimator rejected a sample (%s, %d so far): %s", reason, count, detail)
