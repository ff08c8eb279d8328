"""The measurement-level front end of the EKF: raw GPS / IMU / wheel samples in, pose and innovations out.

It checks every sample (bad ones are counted by reason and logged, never raised), owns the ENU datum,
initialises the filter on the first good fix, learns the heading from motion when nobody gave one, turns
wheel speeds into body motion, and publishes one ``estimator/innovations`` message per update.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from estimator.angles import wrap_angle
from estimator.config import EstimatorConfig
from estimator.ekf import (
    BIAS,
    SCALE,
    SPEED,
    YAW,
    YAW_RATE,
    Innovation,
    RoverEkf,
    Snapshot,
    X,
    Y,
    position_std_m,
)
from estimator.errors import EstimatorSetupError
from estimator.geodesy import Datum, to_enu
from estimator.heading_bootstrap import HeadingBootstrap
from estimator.health import EstimatorHealth
from estimator.history import FusionHistory, GyroSample, HeadingSample, OdometrySample, Sample
from estimator.longitudinal_slip import MAX_BODY_ACCEL_MPS2, STANDARD_GRAVITY_MPS2, LongitudinalSlip
from estimator.pose import PoseEstimate, pose_message
from estimator.stuck import StuckDetector
from estimator.transient import WheelTransient
from estimator.wheels import BodyMotion, side_speeds, six_wheels
from logs.clock import Clock
from logs.sink import MessageSink
from logs.topics import ESTIMATOR_INNOVATIONS, ESTIMATOR_POSE, stamp

logger = logging.getLogger(__name__)


class GpsReset(NamedTuple):
    """A re-anchoring of the position on GPS, after GPS disagreed with the estimate fix after fix for
    ``gps_reset_after_s``: the estimate had been wrong by the jump, at least since ``agreed_until_ns``.
    ``navigator.onboard_home`` moves a home taken from the estimate by it."""

    t_ns: int  # fix time of the fix re-anchored on
    # Fix time of the last fix the estimate agreed with before the disagreement: the last accepted (the
    # first fix, which started the filter, counts) or the last re-anchoring's, whichever is later.
    agreed_until_ns: int
    east_m: float  # the jump: the fix less the estimate at t_ns, ENU metres
    north_m: float


# MAVLink GPS_FIX_TYPE: 3 = 3D fix and better (DGPS, RTK float/fixed). A 2D fix has no usable altitude
# and is often a receiver still settling, so it is refused rather than half-trusted.
MIN_FIX_TYPE = 3
# Heading std while unknown: any direction is as likely as any other.
UNKNOWN_HEADING_STD_RAD = math.pi
# A gyro sample older than this is no evidence about the wheels' current yaw rate.
_GYRO_FRESH_NS = 100_000_000
# Log the first rejection of each kind, then every n-th, so a 50 Hz fault cannot flood the log.
_LOG_EVERY = 100
# Physically impossible readings (a sign or unit error, a corrupted frame): MEMS gyros saturate near
# 35 rad/s (2000 deg/s), accelerometers at 16 g; a rover wheel surface beyond 20 m/s is a decoding error.
_MAX_GYRO_RPS = 35.0
_MAX_ACCEL_MPS2 = 16.0 * STANDARD_GRAVITY_MPS2
_MAX_WHEEL_SPEED_MPS = 20.0
# IMU / wheel samples may arrive this much behind the filter (two sources, one loop); older ones are stale.
_MAX_SAMPLE_LAG_NS = 100_000_000
# A gated fix within this many sigmas (of the difference of two fixes) of the last accepted fix is
# "GPS standing still" evidence for the stuck detector; further away it is a glitch (estimator._fuse_gps).
_STILL_SIGMAS = 3.0
# How far back the fusion history reaches beyond the configured GPS latency (jitter of the link).
_HISTORY_MARGIN_NS = 300_000_000
# An AHRS pitch older than this no longer takes gravity out of the IMU's acceleration (a 5-50 Hz stream).
_PITCH_FRESH_NS = 500_000_000
# The counter of each sensor's accepted updates, named once rather than formatted per update.
_ACCEPTED_KEYS = {sensor: f"{sensor}_accepted" for sensor in ("gyro", "odometry", "heading")}


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
        self._last_gps_reset: GpsReset | None = None
        self._counters: Counter[str] = Counter()
        self._bootstrap = HeadingBootstrap(config.heading_init_distance_m)
        self._initial_heading: tuple[float, float] | None = None
        self._heading_known = False
        self._transient = WheelTransient(config.odom_transient_accel_mps2, config.odom_settle_s)
        self._odometry_seen = False
        self._gps_rejected_since_ns: int | None = None  # fix time of the first gated fix in a row
        self._last_gps_accepted_ns: int | None = None
        self._last_gps_accepted_xy: tuple[float, float] | None = None  # ENU m of the last accepted fix
        self._last_gps_fix_ns: int | None = None
        self._last_gyro: tuple[int, float] | None = None  # (t_ns, raw gyro z rad/s)
        self._last_wheels_ns: int | None = None
        self._stuck = StuckDetector(config.stuck_window_s, config.stuck_min_distance_m)
        self._long_slip = (
            LongitudinalSlip(
                config.long_slip_window_s, config.long_slip_threshold_mps, config.long_slip_max_s
            )
            if config.long_slip_threshold_mps > 0.0
            else None
        )
        self._pitch: tuple[int, float] | None = None  # (t_ns, AHRS pitch rad, nose up positive)
        self._latency_ns = round(config.gps_latency_s * 1e9)
        # Kept only when fixes can be late: every IMU / wheel update then costs a state copy.
        self._history = FusionHistory(self._latency_ns + _HISTORY_MARGIN_NS) if self._latency_ns else None
        # The last pose() at the filter's own time, with the (EKF revision, heading known) it was made
        # from: the control tick asks for it, then publishes it, with nothing fused in between.
        self._pose_cache: tuple[tuple[int, bool], PoseEstimate] | None = None

    # --- read-only views -----------------------------------------------------------------------
    @property
    def datum(self) -> Datum | None:
        return self._datum

    @property
    def last_gps_reset(self) -> GpsReset | None:
        """The last re-anchoring of the position on GPS (``GpsReset``), or None: a new object each time."""
        return self._last_gps_reset

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
            self._cut_history()
        else:
            self._initial_heading = (wrap_angle(yaw_rad), std_rad)
        self._heading_known = True

    def on_attitude(self, t_ns: int, yaw_rad: float, std_rad: float, pitch_rad: float | None = None) -> None:
        """An absolute heading (AHRS / compass yaw, rad CCW from east, std rad), fused as a measurement.

        The first one (before any heading is known) initialises the heading; later ones are gated updates,
        so one noisy AHRS sample does not fix the heading for the whole run. ``pitch_rad`` (nose up
        positive), when finite, takes gravity out of the IMU's longitudinal acceleration
        (``estimator.longitudinal_slip``); a non-finite one is ignored.
        """
        if (
            pitch_rad is not None
            and math.isfinite(pitch_rad)
            and (self._pitch is None or t_ns > self._pitch[0])
        ):
            self._pitch = (t_ns, pitch_rad)
        if not (math.isfinite(yaw_rad) and math.isfinite(std_rad)) or std_rad <= 0.0:
            self._reject("attitude_not_finite", f"yaw={yaw_rad}, std={std_rad}")
            return
        if not self._ekf.initialised or not self._heading_known:
            self.set_initial_heading(yaw_rad, std_rad)
            return
        if t_ns < self._ekf.t_ns - _MAX_SAMPLE_LAG_NS:
            self._reject("attitude_stale", f"sample at {t_ns} ns, filter already at {self._ekf.t_ns} ns")
            return
        ekf = self._ekf
        before = ekf.snapshot() if self._history is not None else None
        self._advance(t_ns)
        innovation = ekf.update_heading(yaw_rad, std_rad)
        if before is not None:
            # At the filter's time (a sample a little older than it is fused there): the history's order.
            self._remember(
                before, HeadingSample(ekf.t_ns, yaw_rad, std_rad, ekf.acceleration, ekf.scale_learning)
            )
        self._report(t_ns, innovation, "heading")

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
        fix_time_ns: int | None = None,
    ) -> None:
        """A GPS fix (WGS84 degrees, metres). ``eph_m`` is the horizontal std (m) or None if unknown.

        ``t_ns`` is when it arrived; the fix was taken at ``fix_time_ns`` if the caller knows it, else
        ``gps_latency_s`` before arrival. ``satellites`` is informational; the receiver's ``fix_type``
        already says whether enough were used.
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
        t_fix = fix_time_ns if fix_time_ns is not None else t_ns - self._latency_ns
        if self._last_gps_fix_ns is not None and t_fix <= self._last_gps_fix_ns:
            previous = self._last_gps_fix_ns
            self._reject("gps_out_of_order", f"fix time {t_fix} ns is not after the previous {previous} ns")
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
        self._last_gps_fix_ns = t_fix

        if not self._ekf.initialised:
            self._initialise(t_fix, east, north, std)
            self._last_gps_accepted_ns = t_fix
            self._last_gps_accepted_xy = (east, north)
            return
        if t_fix < self._ekf.t_ns and self._heading_known:
            self._fuse_late_gps(t_fix, east, north, std)
        else:
            # While the heading is still being learnt the bootstrap must see each motion once, so a late
            # fix is fused on arrival then (a fraction of a second off, at walking speed).
            self._fuse_gps(max(t_fix, self._ekf.t_ns), east, north, std)

    def on_imu(self, t_ns: int, gyro_z_rps: float, accel_x: float, accel_y: float) -> None:
        """Body-frame IMU sample: gyro z (rad/s, CCW positive), accelerations (m/s^2, x forward, y left).

        The accelerations are range-checked. They are not fused as measurements: this planar filter has no
        acceleration state. The longitudinal one, less gravity along the AHRS pitch, tells when the wheels
        slip along their travel, and then carries the speed (``estimator.longitudinal_slip``).
        """
        if not (math.isfinite(gyro_z_rps) and math.isfinite(accel_x) and math.isfinite(accel_y)):
            self._reject("imu_not_finite", f"gyro_z_rps={gyro_z_rps}, accel=({accel_x}, {accel_y})")
            return
        if abs(gyro_z_rps) > _MAX_GYRO_RPS or math.hypot(accel_x, accel_y) > _MAX_ACCEL_MPS2:
            self._reject("imu_out_of_range", f"gyro_z_rps={gyro_z_rps}, accel=({accel_x}, {accel_y})")
            return
        ekf = self._ekf
        if not ekf.initialised:
            self._last_gyro = (t_ns, gyro_z_rps)
            self._counters["imu_before_init"] += 1
            return
        if t_ns < ekf.t_ns - _MAX_SAMPLE_LAG_NS:
            self._reject("imu_stale", f"sample at {t_ns} ns, filter already at {ekf.t_ns} ns")
            return
        if self._long_slip is not None:
            self._take_acceleration(t_ns, accel_x)
        self._last_gyro = (t_ns, gyro_z_rps)
        before = ekf.snapshot() if self._history is not None else None
        if not self._heading_known:
            self._feed_bootstrap(t_ns)
        innovation = ekf.update_gyro(gyro_z_rps, t_ns=t_ns)  # the predict to t_ns in the same call
        if before is not None:
            self._remember(before, GyroSample(t_ns, gyro_z_rps, ekf.acceleration, ekf.scale_learning))
        self._report(t_ns, innovation, "gyro")

    def on_wheels(self, t_ns: int, left_speed_mps: float, right_speed_mps: float) -> None:
        """Mean left and right wheel surface speeds (m/s) -> skid-steer body speed and yaw rate."""
        if not (math.isfinite(left_speed_mps) and math.isfinite(right_speed_mps)):
            self._reject("wheels_not_finite", f"left={left_speed_mps}, right={right_speed_mps}")
            return
        if max(abs(left_speed_mps), abs(right_speed_mps)) > _MAX_WHEEL_SPEED_MPS:
            self._reject("wheels_out_of_range", f"left={left_speed_mps:.2f}, right={right_speed_mps:.2f} m/s")
            return
        motion = side_speeds(left_speed_mps, right_speed_mps, self._config.track_m, self._config.skid_factor)
        self._fuse_wheels(t_ns, motion)

    def on_wheel_speeds(self, t_ns: int, speeds_mps: Sequence[float]) -> None:
        """Six wheel surface speeds (m/s) in wheel order: left front/middle/rear, right front/middle/rear.

        Better than ``on_wheels`` when available: wheels of one side that disagree (one spinning, one
        stalled) make the odometry noise grow by their spread.
        """
        if len(speeds_mps) != 6:
            self._reject("wheels_malformed", f"{len(speeds_mps)} wheel speeds instead of 6")
            return
        # map() over the six: the same tests as a generator expression, without its per-item frame.
        if not all(map(math.isfinite, speeds_mps)):
            self._reject("wheels_not_finite", f"speeds={list(speeds_mps)}")
            return
        if max(map(abs, speeds_mps)) > _MAX_WHEEL_SPEED_MPS:
            self._reject("wheels_out_of_range", f"speeds={_cm(speeds_mps)} m/s")
            return
        self._fuse_wheels(t_ns, six_wheels(speeds_mps, self._config.track_m, self._config.skid_factor))

    # --- output --------------------------------------------------------------------------------
    def pose(self, t_ns: int | None = None) -> PoseEstimate | None:
        """The estimate, extrapolated to ``t_ns`` if later than the last sample; None before the first fix.

        Asked again with nothing fused since (same EKF revision), it is the same object: the control tick
        reads the pose, then publishes it. Its covariance is read-only.
        """
        ekf = self._ekf
        made_from = (ekf.revision, self._heading_known)
        cached = self._pose_cache
        # The common case first (twice per control tick): nothing fused since the last answer. The same
        # revision means the same filter time too, so only a later ``t_ns`` needs more.
        if cached is not None and cached[0] == made_from and (t_ns is None or t_ns <= cached[1].t_ns):
            return cached[1]
        if not ekf.initialised:
            return None
        if t_ns is not None and t_ns > ekf.t_ns:
            x, p = ekf.predicted(t_ns)
            return self._pose_of(x.tolist(), p, t_ns)
        pose = self._pose_of(ekf.state_values(), ekf.covariance, ekf.t_ns)
        self._pose_cache = (made_from, pose)
        return pose

    def _pose_of(self, x: list[float], p: NDArray[np.float64], t_ns: int) -> PoseEstimate:
        """The estimate of state ``x`` and covariance ``p`` at ``t_ns``, judged as ``health`` judges it
        (only the flags ``healthy`` needs: no ``EstimatorHealth`` built every tick)."""
        config = self._config
        # The pose's own copy, handed to every reader until the filter changes. setflags: the same flag
        # without building the array's flags object on every tick.
        p.setflags(write=False)
        position_std = position_std_m(p)
        healthy = (
            position_std < config.healthy_position_std_m
            and self._heading_known
            and _heading_std_deg(p) < config.healthy_heading_std_deg
        )
        # Positional, in the field order (x, y, yaw, speed, yaw rate, covariance, healthy, t, heading
        # known, position std): keywords cost a dict per call.
        return PoseEstimate(
            x[X], x[Y], x[YAW], x[SPEED], x[YAW_RATE], p, healthy, t_ns, self._heading_known, position_std
        )

    def health(self) -> EstimatorHealth:
        """Health flags of the current estimate, each with the threshold it was judged against."""
        return self._health(self._ekf.covariance if self._ekf.initialised else None)

    @property
    def odometry_scale(self) -> float:
        """Learnt wheel-speed / ground-speed ratio (1 on firm ground)."""
        return self._ekf.state(SCALE) if self._ekf.initialised else 1.0

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

    def _fuse_gps(self, t_fix: int, east: float, north: float, std: float) -> None:
        self._advance(t_fix)
        # Until the heading is known the covariance rests on a linearisation that may be far off, so the
        # gate would throw away exactly the fixes that teach us the heading.
        innovation = self._ekf.update_position(east, north, std, gated=self._heading_known)
        self._report(t_fix, innovation, None)  # counted below, with the GPS's own reasons
        if not self._heading_known:
            self._learn_heading(east, north, std)
        if innovation.accepted:
            self._gps_accepted(t_fix)
            self._last_gps_accepted_xy = (east, north)
            self._judge_spinning(t_fix, east, north, std)
            return
        if self._spin_signature(east, north, std, innovation.residual):
            # Wheels spinning in place dead-reckon the estimate away from a GPS that stands still, so the
            # gate soon throws out the very fixes that show it; those still count as evidence.
            self._judge_spinning(t_fix, east, north, std)
        self._reject("gps_gated", f"NIS {innovation.nis:.1f}, residual {_cm(innovation.residual)} m")
        if self._gps_rejected_since_ns is None:
            self._gps_rejected_since_ns = t_fix
        gated_for_s = (t_fix - self._gps_rejected_since_ns) * 1e-9
        if gated_for_s >= self._config.gps_reset_after_s:
            # GPS has disagreed with us for long, fix after fix: more likely we drifted (or the wheels
            # lied) than that GPS is wrong for so long. A short glitch never gets here.
            ekf = self._ekf
            jump_east, jump_north = east - ekf.state(X), north - ekf.state(Y)  # at t_fix (_advance above)
            agreed = self._agreed_until_ns()
            self._last_gps_reset = GpsReset(t_fix, agreed, jump_east, jump_north)
            ekf.reset_position(east, north, std)
            self._last_gps_accepted_xy = (east, north)
            self._counters["gps_reset"] += 1
            logger.warning(
                "GPS gated out for %.1f s; position re-anchored on GPS at (%.1f, %.1f) m",
                gated_for_s,
                east,
                north,
            )
            self._gps_rejected_since_ns = None

    def _agreed_until_ns(self) -> int:
        """Fix time of the last fix the estimate agreed with: the last accepted, or the last re-anchoring's
        (the estimate was put on that fix), whichever is later. A re-anchoring is not counted as accepted
        (``_last_gps_accepted_ns`` says how fresh GPS is for health), but it is an agreement: without it a
        second long disagreement right after the first would carry the first's time, and read as the
        estimate having been off since then (``navigator.onboard_home`` would move home twice)."""
        times = [self._last_gps_accepted_ns]
        if self._last_gps_reset is not None:
            times.append(self._last_gps_reset.t_ns)
        # The first fix, which started the filter, is accepted: only a filter never started has neither.
        return max((t for t in times if t is not None), default=0)

    def _judge_spinning(self, t_fix: int, east: float, north: float, std: float) -> None:
        was_spinning = self._stuck.spinning
        if self._stuck.on_fix(t_fix, east, north, std) != was_spinning:
            self._on_spinning_changed()

    def _spin_signature(self, east: float, north: float, std: float, residual: tuple[float, ...]) -> bool:
        """Whether a gated fix looks like wheels spinning in place: where the last accepted fix was
        (within the noise of the two fixes) and behind the estimate along its direction of travel.

        Only such a fix is evidence about the wheels: the spin hypothesis is "the ground stands still
        while odometry runs the estimate ahead". A glitch jumps away (sideways, or ahead of the estimate),
        and a jumped fix fed to the stuck detector made a 3 m glitch read as 2 m of wheel spin (whose
        covariance inflation then let the next glitched fixes through the gate). A glitch straight back
        along the track can still pass for a while (docs/estimator.md).
        """
        last = self._last_gps_accepted_xy
        if last is None or math.dist((east, north), last) > _STILL_SIGMAS * math.sqrt(2.0) * std:
            return False
        yaw, speed = self._ekf.state(YAW), self._ekf.state(SPEED)
        ahead_m = residual[0] * math.cos(yaw) + residual[1] * math.sin(yaw)  # fix minus prior, m
        return ahead_m * speed < 0.0

    def _fuse_late_gps(self, t_fix: int, east: float, north: float, std: float) -> None:
        """Rewind to the fix's time, fuse it there, and re-fuse the IMU / wheel samples since."""
        history = self._history
        if history is None or not history.covers(t_fix):
            if (
                history is not None
                and history.cut_after(t_fix)
                and self._ekf.t_ns - t_fix <= history.horizon_ns
            ):
                # Taken before the heading was given or learnt: fused on arrival, as while it was unknown.
                self._counters["gps_fused_on_arrival"] += 1
                self._fuse_gps(self._ekf.t_ns, east, north, std)
                return
            self._reject("gps_too_late", f"fix time {t_fix} ns is older than the fusion history")
            return
        later = history.rewind(self._ekf, t_fix)
        self._fuse_gps(t_fix, east, north, std)
        history.replay(self._ekf, later)
        self._counters["gps_fused_late"] += 1

    def _fuse_wheels(self, t_ns: int, motion: BodyMotion) -> None:
        ekf = self._ekf
        if not ekf.initialised:
            self._counters["wheels_before_init"] += 1
            return
        if t_ns < ekf.t_ns - _MAX_SAMPLE_LAG_NS:
            self._reject("wheels_stale", f"sample at {t_ns} ns, filter already at {ekf.t_ns} ns")
            return
        last_wheels_ns = self._last_wheels_ns
        if last_wheels_ns is not None and t_ns > last_wheels_ns:
            self._stuck.add_odometry(t_ns, motion.speed_mps * (t_ns - last_wheels_ns) * 1e-9, ekf.state(YAW))
        self._last_wheels_ns = t_ns
        self._transient.add(t_ns, motion.speed_mps)
        speed_std, yaw_rate_std = self._odometry_noise(t_ns, motion)
        use_speed = not self._stuck.spinning
        before = ekf.snapshot() if self._history is not None else None
        speed_reset = None
        if self._long_slip is not None:
            slipping, speed_reset = self._judge_long_slip(t_ns, motion.speed_mps)
            if slipping:
                self._counters["odometry_long_slip"] += 1
                use_speed = False
        if not use_speed:
            self._counters["odometry_speed_left_out"] += 1
        if not self._heading_known:
            self._feed_bootstrap(t_ns)
        ekf.learn_scale(self._scale_observable(t_ns))
        # The predict to t_ns in the same compiled call as the update.
        innovation = ekf.update_odometry(
            motion.speed_mps, motion.yaw_rate_rps, speed_std, yaw_rate_std, use_speed=use_speed, t_ns=t_ns
        )
        if before is not None:
            sample = OdometrySample(
                t_ns,
                motion.speed_mps,
                motion.yaw_rate_rps,
                speed_std,
                yaw_rate_std,
                use_speed,
                ekf.acceleration,
                speed_reset,
                ekf.scale_learning,
            )
            self._remember(before, sample)
        self._odometry_seen = True
        self._report(t_ns, innovation, "odometry")

    def _take_acceleration(self, t_ns: int, accel_x: float) -> None:
        """The IMU's longitudinal specific force as the body's acceleration, gravity along the slope taken
        out with the AHRS pitch; while the wheels slip, the EKF's speed follows it."""
        assert self._long_slip is not None
        pitch = self._pitch
        if pitch is None or abs(t_ns - pitch[0]) > _PITCH_FRESH_NS:
            # Without the pitch, a 5 deg slope reads as 0.85 m/s^2: no acceleration is better than that.
            if self._long_slip.body_unknown():
                self._counters["odometry_long_slip_no_pitch"] += 1
                self._counters["odometry_long_slip_off"] += 1
            self._ekf.acceleration = 0.0
            return
        body = accel_x - STANDARD_GRAVITY_MPS2 * math.sin(pitch[1])
        if not self._long_slip.add_body_acceleration(t_ns, body):
            if abs(body) > MAX_BODY_ACCEL_MPS2:
                self._counters["imu_accel_knock"] += 1
            return
        if self._long_slip.slipping:
            self._ekf.acceleration = body

    def _judge_long_slip(self, t_ns: int, wheel_speed_mps: float) -> tuple[bool, tuple[float, float] | None]:
        """Whether this odometry sample's wheels slip along their travel (``estimator.longitudinal_slip``),
        and the speed reset made as a slip begins, if one did; sets the EKF's acceleration input to match.

        A slip is told a few samples into it, which the filter took from the wheels: its speed is put back
        to the body's, as the IMU says it changed over the window."""
        slip = self._long_slip
        assert slip is not None
        ekf = self._ekf
        was = slip.slipping
        scale = ekf.state(SCALE)
        slipping = slip.judge(t_ns, wheel_speed_mps, scale * ekf.state(SPEED))
        ekf.acceleration = slip.body_acceleration if slipping else 0.0
        if slipping == was:
            return slipping, None
        self._counters["odometry_long_slip_on" if slipping else "odometry_long_slip_off"] += 1
        if not slipping:
            return False, None
        reset = (slip.body_speed_at_start_mps / scale, 0.5 * self._config.long_slip_threshold_mps)
        ekf.reset_speed(*reset)
        return True, reset

    def _on_spinning_changed(self) -> None:
        spinning = self._stuck.spinning
        self._counters["odometry_spinning_on" if spinning else "odometry_spinning_off"] += 1
        logger.warning(
            "wheels %s (odometry ran %.1f m ahead of GPS over %.1f s)",
            "spinning in place: odometry speed left out" if spinning else "grip again",
            self._stuck.shortfall_m,
            self._config.stuck_window_s,
        )
        if spinning and self._stuck.shortfall_m > 0.0:
            # The position and speed were dead-reckoned from the spinning wheels until now: they are off
            # by about what odometry ran ahead. Saying so lets the next fixes through the gate at once.
            self._ekf.inflate(X, self._stuck.shortfall_m)
            self._ekf.inflate(Y, self._stuck.shortfall_m)
            self._ekf.inflate(SPEED, max(abs(self._ekf.state(SPEED)), self._config.odom_speed_noise_mps))

    def _scale_observable(self, t_ns: int) -> bool:
        """The odometry scale is learnt only against GPS track with a known heading and gripping wheels."""
        last_fix = self._last_gps_accepted_ns
        gps_recent = last_fix is not None and t_ns - last_fix <= self._config.gps_timeout_s * 1e9
        steady = not self._transient.unsettled(t_ns)
        return gps_recent and self._heading_known and steady and not self._stuck.spinning

    def _cut_history(self) -> None:
        if self._history is not None:
            self._history.cut(self._ekf.t_ns)

    def _remember(self, before: Snapshot, sample: Sample) -> None:
        if self._history is not None:
            self._history.record(before, sample)

    def _gps_accepted(self, t_fix: int) -> None:
        self._gps_rejected_since_ns = None
        self._last_gps_accepted_ns = t_fix
        self._counters["gps_accepted"] += 1

    def _health(self, p: NDArray[np.float64] | None) -> EstimatorHealth:
        config = self._config
        if self._last_gps_accepted_ns is None:
            gps_age_s = math.inf
        else:
            gps_age_s = max(self._clock.now_ns() - self._last_gps_accepted_ns, 0) * 1e-9
        return EstimatorHealth(
            initialised=p is not None,
            heading_known=self._heading_known,
            position_std_m=position_std_m(p) if p is not None else math.inf,
            position_std_limit_m=config.healthy_position_std_m,
            heading_std_deg=_heading_std_deg(p) if p is not None else math.inf,
            heading_std_limit_deg=config.healthy_heading_std_deg,
            gps_age_s=gps_age_s,
            gps_timeout_s=config.gps_timeout_s,
            odometry_trusted=not self._stuck.spinning,
        )

    def _advance(self, t_ns: int) -> None:
        """Predict to ``t_ns``, feeding the heading bootstrap the motion the filter believes in meanwhile."""
        if not self._heading_known:
            self._feed_bootstrap(t_ns)
        self._ekf.predict(t_ns)

    def _feed_bootstrap(self, t_ns: int) -> None:
        """For a caller that knows the heading is unknown: the motion the filter believes in up to ``t_ns``
        (it is about to predict there) goes to the heading bootstrap."""
        dt_ns = t_ns - self._ekf.t_ns
        if dt_ns > 0:
            dt = dt_ns * 1e-9
            self._bootstrap.add_motion(
                self._ekf.state(YAW_RATE) * dt, self._ekf.state(SPEED) * dt if self._odometry_seen else 0.0
            )

    def _learn_heading(self, east: float, north: float, std: float) -> None:
        guess = self._bootstrap.on_fix(east, north, std, path_known=self._odometry_seen)
        if guess is None:
            return
        self._heading_known = True
        # Late fixes were fused on arrival until now, so the history's states are not at their times.
        self._cut_history()
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

    def _odometry_noise(self, t_ns: int, motion: BodyMotion) -> tuple[float, float]:
        """Odometry std (speed m/s, yaw rate rad/s), inflated when the wheels are seen to slip.

        Skid-steer wheels slip all the time on turns and loose ground. Two signs of it: the odometry yaw
        rate departs from the bias-corrected gyro by more than the threshold (trust the wheels less in
        proportion), and the wheels of one side disagree (the side's ground speed is then uncertain by
        about their spread).
        """
        config = self._config
        speed_std = max(config.odom_speed_noise_mps, motion.side_spread_mps)
        yaw_rate_std = math.hypot(
            config.odom_yaw_rate_noise_rps, config.odom_yaw_rate_relative_noise * motion.yaw_rate_rps
        )
        if motion.side_spread_mps > self._config.odom_speed_noise_mps:
            self._counters["odometry_wheel_spread"] += 1
        if self._last_gyro is None or abs(t_ns - self._last_gyro[0]) > _GYRO_FRESH_NS:
            return speed_std, yaw_rate_std
        gyro_rate = self._last_gyro[1] - self._ekf.state(BIAS)
        mismatch = abs(motion.yaw_rate_rps - gyro_rate)
        if mismatch <= self._config.slip_threshold_rps:
            return speed_std, yaw_rate_std
        self._counters["odometry_slip"] += 1
        factor = mismatch / self._config.slip_threshold_rps
        return speed_std * factor, max(yaw_rate_std * factor, mismatch)

    def _report(self, t_ns: int, innovation: Innovation, sensor: str | None) -> None:
        """Publish an update's innovation and count it under ``sensor`` ("gyro", "odometry", "heading"),
        accepted or gated; ``sensor`` None: publish only (one call for the two: two per control tick)."""
        self._sink.publish(
            ESTIMATOR_INNOVATIONS,
            self._clock.now_ns(),
            {
                "timestamp": stamp(t_ns),
                "sensor": innovation.sensor,
                "innovation": list(innovation.residual),
                "nis": innovation.nis,
                "accepted": innovation.accepted,
            },
        )
        if sensor is None:
            return
        if innovation.accepted:
            self._counters[_ACCEPTED_KEYS[sensor]] += 1
        else:
            self._reject(f"{sensor}_gated", f"NIS {innovation.nis:.1f}, residual {_cm(innovation.residual)}")

    def _reject(self, reason: str, detail: str) -> None:
        self._counters[reason] += 1
        count = self._counters[reason]
        if count == 1 or count % _LOG_EVERY == 0:
            logger.warning("estimator rejected a sample (%s, %d so far): %s", reason, count, detail)


def _heading_std_deg(p: NDArray[np.float64]) -> float:
    """Heading std (degrees) of a state covariance."""
    return math.degrees(math.sqrt(max(p.item(YAW, YAW), 0.0)))


def _cm(values: Sequence[float]) -> str:
    """Values (m, m/s) for a log line: centimetres, not the 16 digits of a float repr."""
    return "(" + ", ".join(f"{v:.2f}" for v in values) + ")"
