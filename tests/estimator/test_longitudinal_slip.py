"""Wheels slipping along their travel (braking skids, launch spin), told from the IMU: the detector alone,
then the estimator through a braking skid on a slope."""

import math
from collections.abc import Callable

import numpy as np
import pytest

from estimator.config import EstimatorConfig
from estimator.ekf import SCALE, SPEED, RoverEkf, X
from estimator.estimator import Estimator
from estimator.geodesy import to_geodetic
from estimator.history import GyroSample, OdometrySample, apply
from estimator.longitudinal_slip import LongitudinalSlip
from logs.clock import SimClock
from logs.sink import MemorySink
from tests.estimator.sim_run import SIM_DATUM

MS = 1_000_000
G = 9.80665


def _feed(slip: LongitudinalSlip, t_ms: int, wheels: float, body_accel: float, estimate: float) -> bool:
    slip.add_body_acceleration(t_ms * MS, body_accel)
    return slip.judge(t_ms * MS, wheels, estimate)


def test_wheels_stopping_faster_than_the_body_slows_is_a_slip_until_they_agree_again():
    slip = LongitudinalSlip(window_s=0.25, threshold_mps=0.15, max_s=1.5)
    for t in range(0, 500, 20):  # cruising at 0.5 m/s: wheels and body agree
        assert not _feed(slip, t, 0.5, 0.0, 0.5)
    # The wheels stop within 0.1 s; the body slows at 1 m/s^2 (the estimate follows it).
    started_at = None
    for t in range(500, 1000, 20):
        wheels = max(0.0, 0.5 - 5.0 * (t - 480) / 1000)
        body = max(0.0, 0.5 - 1.0 * (t - 480) / 1000)
        if _feed(slip, t, wheels, -1.0 if body > 0.0 else 0.0, body) and started_at is None:
            started_at = t
    assert started_at is not None and started_at <= 560  # told within a few samples
    # At its start, the body's speed: 0.5 m/s less 1 m/s^2 since the brake (within a sample's 0.02 m/s).
    assert slip.body_speed_at_start_mps == pytest.approx(0.5 - (started_at - 480) / 1000, abs=0.021)
    # It ended when the body's speed came within 0.075 m/s of the wheels' 0 (at 0.41 s), and no second
    # slip began on the same transient's samples, still in the window.
    assert not slip.slipping
    assert (slip.started, slip.timed_out) == (1, 0)


def test_wheels_and_body_that_change_speed_together_are_no_slip():
    slip = LongitudinalSlip(window_s=0.25, threshold_mps=0.15, max_s=1.5)
    for t in range(0, 2000, 20):  # braking at 2 m/s^2 from 1 m/s, with the body
        speed = max(0.0, 1.0 - 2.0 * t / 1000)
        assert not _feed(slip, t, speed, -2.0 if speed > 0.0 else 0.0, speed)
    assert slip.started == 0


def test_a_slip_that_never_ends_is_given_up_after_max_s():
    slip = LongitudinalSlip(window_s=0.25, threshold_mps=0.15, max_s=0.5)
    for t in range(0, 300, 20):
        _feed(slip, t, 0.0, 0.0, 0.0)
    # The wheels spin up, the body does not move at all: one sample is a suspicion, the second a slip.
    assert not _feed(slip, 300, 1.0, 0.0, 0.0)
    assert _feed(slip, 320, 1.0, 0.0, 0.0)
    results = [_feed(slip, t, 1.0, 0.0, 0.0) for t in range(340, 900, 20)]
    assert results.index(False) == (820 - 340) // 20  # 0.5 s after it began, and not again at once
    assert slip.timed_out == 1


def test_without_the_body_acceleration_there_is_no_judgement_and_a_slip_ends():
    slip = LongitudinalSlip(window_s=0.25, threshold_mps=0.15, max_s=1.5)
    for t in range(0, 300, 20):  # wheel samples only: nothing to compare them with
        assert not slip.judge(t * MS, 0.0 if t < 200 else 1.0, 0.0)
    assert slip.started == 0
    started = slip.started
    for t in range(300, 1000, 20):  # standing, with the body's acceleration again: the wheels are judged
        _feed(slip, t, 0.0, 0.0, 0.0)
    assert slip.started == started + 1  # the wheels' drop at 0.3 s, once the IMU covered its window
    assert not _feed(slip, 1000, 1.0, 0.0, 0.0)
    assert _feed(slip, 1020, 1.0, 0.0, 0.0)
    slip.body_unknown()
    assert not slip.slipping


def test_the_ekf_speed_follows_its_acceleration_input_and_a_snapshot_keeps_it():
    ekf = RoverEkf(EstimatorConfig())
    ekf.initialise(0.0, 0.0, 0.0, 0, position_std_m=0.5, yaw_std_rad=0.1)
    ekf.reset_speed(1.0, 0.05)
    speed = ekf.state(SPEED)
    ekf.acceleration = -2.0
    before = ekf.snapshot()
    ekf.predict(100 * MS)
    assert speed == 1.0
    assert ekf.state(SPEED) == pytest.approx(speed - 0.2)
    assert ekf.state(X) == pytest.approx((speed - 0.1) * 0.1)  # (v + a dt / 2) dt
    ekf.acceleration = 0.0
    ekf.restore(before)
    assert ekf.acceleration == -2.0


class _Skid:
    """A rover driving at 0.5 m/s (east, or reversing west with ``direction=-1``) up a 5 deg slope, then
    braking: its wheels stop within 0.1 s, its body slides on, slowing at 1 m/s^2 (0.125 m in 0.5 s). GPS
    fixes (5 Hz) are taken until the brake begins, so where the estimate ends up is dead reckoning through
    the skid. Wheels and IMU at 50 Hz, AHRS at 10 Hz.

    ``brake=False``: it cruises on. ``imu_extra(t_ms)`` is added to the IMU's x (a knock, vibration);
    ``pitch_of(t_ms)`` replaces the constant slope, and the AHRS reports the pitch of ``attitude_lag_ms``
    before. ``gps_latency_ms``: each fix reaches the estimator that much after it was taken (the config's
    ``gps_latency_s`` should say so).
    """

    PITCH = math.radians(5.0)
    BRAKE_MS = 4000

    def __init__(
        self,
        config: EstimatorConfig,
        *,
        with_attitude: bool = True,
        brake: bool = True,
        direction: int = 1,
        imu_extra: Callable[[int], float] = lambda t_ms: 0.0,
        pitch_of: Callable[[int], float] | None = None,
        attitude_lag_ms: int = 0,
        gps_latency_ms: int = 0,
    ) -> None:
        self.estimator = Estimator(config, SimClock(), MemorySink())
        self.estimator.set_initial_heading(0.0, 0.01)
        self.direction = direction
        pitch = pitch_of or (lambda t_ms: self.PITCH)
        self.true_x = 0.0
        speed = 0.5
        fixes: list[tuple[int, float]] = []  # (taken at ms, true x then)
        for t in range(0, self.BRAKE_MS + 1500, 20):
            braking = brake and t >= self.BRAKE_MS
            body_accel = -1.0 if braking and speed > 0.0 else 0.0
            wheels = max(0.0, 0.5 - 5.0 * (t - self.BRAKE_MS + 20) / 1000) if braking else 0.5
            t_ns = t * MS
            if not braking and t % 200 == 0:
                fixes.append((t, self.true_x))
            while fixes and fixes[0][0] + gps_latency_ms <= t:
                _, x = fixes.pop(0)
                lat, lon, alt = to_geodetic(SIM_DATUM, x, 0.0, 0.0)
                self.estimator.on_gps(t_ns, lat, lon, alt, 3, 0.05, 12)
            if with_attitude and t % 100 == 0:
                # Reversing, the rover faces east still: the slope's pitch is the same, its travel is not.
                self.estimator.on_attitude(t_ns, 0.0, 0.05, pitch_rad=pitch(t - attitude_lag_ms))
            # Specific force along the body's x: its acceleration (along its travel) plus gravity's share.
            specific_force = direction * body_accel + G * math.sin(pitch(t)) + imu_extra(t)
            self.estimator.on_imu(t_ns, 0.0, specific_force, 0.0)
            self.estimator.on_wheel_speeds(t_ns, [direction * wheels] * 6)
            self.true_x += direction * max(0.0, speed * 0.02 + 0.5 * body_accel * 0.02**2)
            speed = max(0.0, speed + body_accel * 0.02)
        self.brake_x = direction * 0.5 * self.BRAKE_MS / 1000  # where the brake began

    @property
    def slid_estimate_m(self) -> float:
        """How far the estimate moved from where the brake began, along the travel."""
        pose = self.estimator.pose()
        assert pose is not None
        return self.direction * (pose.x - self.brake_x)

    @property
    def slid_m(self) -> float:
        return self.direction * (self.true_x - self.brake_x)


def test_a_braking_skid_on_a_slope_is_dead_reckoned_with_the_imu():
    skid = _Skid(EstimatorConfig())
    assert skid.slid_m == pytest.approx(0.125, abs=0.01)
    # 0.097 m of the body's 0.125 m when this was written (the wheels alone: 0.013 m, the next test). The
    # rest is the samples before the slip was told, and the last centimetres/s after the wheels agreed.
    assert 0.09 <= skid.slid_estimate_m <= skid.slid_m + 0.01
    counters = skid.estimator.counters
    assert counters["odometry_long_slip_on"] == 1
    assert counters["odometry_long_slip_off"] == 1  # the wheels and the estimate agree again, at rest
    pose = skid.estimator.pose()
    assert pose is not None and abs(pose.speed) < 0.05


def test_without_it_the_estimate_stops_with_the_wheels():
    """The same skid with the detector off, or with no AHRS pitch to take gravity out: the estimate
    believes the wheels and stops half as far as the body slid."""
    for skid in (
        _Skid(EstimatorConfig(long_slip_threshold_mps=0.0)),
        _Skid(EstimatorConfig(), with_attitude=False),
    ):
        assert skid.slid_estimate_m < 0.08
        assert "odometry_long_slip_on" not in skid.estimator.counters


def test_driving_up_the_slope_at_constant_speed_is_no_slip():
    """Gravity's 0.85 m/s^2 along a 5 deg slope, taken out with the pitch: no false slip, and the estimate
    is where the rover is."""
    cruise = _Skid(EstimatorConfig(), brake=False)
    assert "odometry_long_slip_on" not in cruise.estimator.counters
    pose = cruise.estimator.pose()
    assert pose is not None and pose.x == pytest.approx(cruise.true_x, abs=0.05)


def test_a_replayed_sample_redoes_its_speed_reset_and_acceleration():
    """After a late GPS fix the history re-fuses the samples since it (``estimator.history.apply``): they
    must move the filter as the estimator's first pass did, with the slip's reset and the IMU's input."""
    first, replayed = (RoverEkf(EstimatorConfig()) for _ in range(2))
    for ekf in (first, replayed):
        ekf.initialise(0.0, 0.0, 0.0, 0, position_std_m=0.5, yaw_std_rad=0.1)
        ekf.reset_speed(0.5, 0.05)
    # The first pass, as Estimator._fuse_wheels makes it.
    first.reset_speed(0.46, 0.075)
    first.acceleration = -1.0
    first.update_odometry(0.0, 0.0, 0.05, 0.05, use_speed=False, t_ns=40 * MS)
    first.update_gyro(0.0, t_ns=60 * MS)
    replayed.acceleration = 0.0  # whatever the filter held when it was rewound
    apply(replayed, OdometrySample(40 * MS, 0.0, 0.0, 0.05, 0.05, False, -1.0, (0.46, 0.075)))
    apply(replayed, GyroSample(60 * MS, 0.0, -1.0))
    assert first.state(SPEED) == pytest.approx(0.46 - 1.0 * 0.06)
    assert replayed.state_values() == first.state_values()
    assert (replayed.covariance == first.covariance).all()


def test_reversing_into_a_skid_is_the_same_skid():
    forward = _Skid(EstimatorConfig())
    backward = _Skid(EstimatorConfig(), direction=-1)
    assert backward.slid_m == pytest.approx(forward.slid_m)
    assert backward.slid_estimate_m == pytest.approx(forward.slid_estimate_m, abs=0.005)
    assert backward.estimator.counters["odometry_long_slip_on"] == 1


def test_a_late_fix_replayed_across_the_skid_keeps_what_the_imu_carried():
    """Fixes taken before the brake reach the estimator 0.2 s late, in the skid: each rewinds the filter to
    its time and re-fuses the samples since, the slip's speed reset and IMU acceleration among them."""
    on_time = _Skid(EstimatorConfig())
    late = _Skid(EstimatorConfig(gps_latency_s=0.2), gps_latency_ms=200)
    assert late.estimator.counters["gps_fused_late"] > 0
    assert late.estimator.counters["odometry_long_slip_on"] == 1
    assert late.slid_estimate_m == pytest.approx(on_time.slid_estimate_m, abs=0.01)


def test_a_knock_on_the_imu_while_cruising_is_no_slip():
    """One 20 ms spike of 8 m/s^2 (a bump), then one of 20 m/s^2, the wheels steady: no slip begins (a
    slip is the wheels' transient), and the 20 m/s^2 one is beyond 1 g: left out as a knock."""
    cruise = _Skid(EstimatorConfig(), brake=False, imu_extra=lambda t: {2000: 8.0, 3000: 20.0}.get(t, 0.0))
    counters = cruise.estimator.counters
    assert "odometry_long_slip_on" not in counters
    assert counters["imu_accel_knock"] == 1
    pose = cruise.estimator.pose()
    assert pose is not None and pose.x == pytest.approx(cruise.true_x, abs=0.05)


def test_vibration_on_rough_ground_starts_no_slip_while_cruising_and_the_skid_is_still_told():
    """White vibration of 2 m/s^2 rms along x on every IMU sample."""
    rng = np.random.default_rng(7)
    shakes = {t: float(rng.normal(0.0, 2.0)) for t in range(0, 6000, 20)}
    cruise = _Skid(EstimatorConfig(), brake=False, imu_extra=shakes.__getitem__)
    assert "odometry_long_slip_on" not in cruise.estimator.counters
    skid = _Skid(EstimatorConfig(), imu_extra=shakes.__getitem__)
    assert skid.estimator.counters["odometry_long_slip_on"] >= 1
    assert skid.slid_estimate_m == pytest.approx(skid.slid_m, abs=0.06)


def test_a_lagging_pitch_on_a_changing_slope_is_no_slip():
    """The slope steepens from 0 to 10 deg over 1 s while the rover cruises; the AHRS reports the pitch
    100 ms late (gravity's share then reads as up to 0.17 m/s^2 of acceleration)."""

    def ramp(t_ms: int) -> float:
        return math.radians(10.0) * min(1.0, max(0.0, (t_ms - 2000) / 1000))

    cruise = _Skid(EstimatorConfig(), brake=False, pitch_of=ramp, attitude_lag_ms=100)
    assert "odometry_long_slip_on" not in cruise.estimator.counters
    pose = cruise.estimator.pose()
    assert pose is not None and pose.x == pytest.approx(cruise.true_x, abs=0.05)


def test_a_replayed_sample_learns_the_odometry_scale_only_if_its_first_pass_could():
    """The scale is only considered while it is unobservable (``Estimator._scale_observable``); a replay
    must not learn it where the first pass did not (a review measured 6e-7 of scale drift per replay)."""
    ekf = RoverEkf(EstimatorConfig())
    ekf.initialise(0.0, 0.0, 0.0, 0, position_std_m=0.5, yaw_std_rad=0.1)
    ekf.reset_speed(1.0, 0.05)
    ekf.learn_scale(True)  # what the filter was doing when it was rewound
    scale = ekf.state(SCALE)
    apply(ekf, OdometrySample(20 * MS, 1.2, 0.0, 0.05, 0.05, True, learn_scale=False))
    assert ekf.state(SCALE) == scale
    assert not ekf.scale_learning
    apply(ekf, OdometrySample(40 * MS, 1.2, 0.0, 0.05, 0.05, True, learn_scale=True))
    assert ekf.state(SCALE) > scale
