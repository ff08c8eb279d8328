"""Wheels slipping along their travel (braking skids, launch spin), told from the IMU: the detector alone,
then the estimator through a braking skid on a slope."""

import math

import pytest

from estimator.config import EstimatorConfig
from estimator.ekf import SPEED, RoverEkf, X
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
    assert _feed(slip, 300, 1.0, 0.0, 0.0)  # the wheels spin up, the body does not move at all
    results = [_feed(slip, t, 1.0, 0.0, 0.0) for t in range(320, 900, 20)]
    assert results.index(False) == (800 - 320) // 20  # 0.5 s after it began, and not again at once
    assert slip.timed_out == 1


def test_without_the_body_acceleration_there_is_no_judgement_and_a_slip_ends():
    slip = LongitudinalSlip(window_s=0.25, threshold_mps=0.15, max_s=1.5)
    for t in range(0, 300, 20):  # wheel samples only: nothing to compare them with
        assert not slip.judge(t * MS, 0.0 if t < 200 else 1.0, 0.0)
    assert slip.started == 0
    started = slip.started
    for t in range(300, 1000, 20):  # standing, with the body's acceleration again: the wheels are judged
        _feed(slip, t, 0.0, 0.0, 0.0)
    assert slip.started == started + 1  # the wheels' step at 0.2 s, once the IMU covered its window
    assert _feed(slip, 1000, 1.0, 0.0, 0.0)
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
    """A rover driving east at 0.5 m/s up a 5 deg slope, then braking: its wheels stop within 0.1 s, its
    body slides on, slowing at 1 m/s^2 (0.125 m in 0.5 s). GPS fixes (5 Hz) stop when the brake begins, so
    where the estimate ends up is dead reckoning through the skid. Wheels and IMU at 50 Hz, AHRS at 10 Hz.
    """

    PITCH = math.radians(5.0)
    BRAKE_MS = 4000

    def __init__(self, config: EstimatorConfig, *, with_attitude: bool = True, brake: bool = True) -> None:
        self.estimator = Estimator(config, SimClock(), MemorySink())
        self.estimator.set_initial_heading(0.0, 0.01)
        self.true_x = 0.0
        speed = 0.5
        for t in range(0, self.BRAKE_MS + 1500, 20):
            braking = brake and t >= self.BRAKE_MS
            body_accel = -1.0 if braking and speed > 0.0 else 0.0
            wheels = max(0.0, 0.5 - 5.0 * (t - self.BRAKE_MS + 20) / 1000) if braking else 0.5
            t_ns = t * MS
            if not braking and t % 200 == 0:
                lat, lon, alt = to_geodetic(SIM_DATUM, self.true_x, 0.0, 0.0)
                self.estimator.on_gps(t_ns, lat, lon, alt, 3, 0.05, 12)
            if with_attitude and t % 100 == 0:
                self.estimator.on_attitude(t_ns, 0.0, 0.05, pitch_rad=self.PITCH)
            # Specific force along the body's x: its acceleration plus gravity's share up the slope.
            self.estimator.on_imu(t_ns, 0.0, body_accel + G * math.sin(self.PITCH), 0.0)
            self.estimator.on_wheel_speeds(t_ns, [wheels] * 6)
            self.true_x += max(0.0, speed * 0.02 + 0.5 * body_accel * 0.02**2)
            speed = max(0.0, speed + body_accel * 0.02)
        self.brake_x = 0.5 * self.BRAKE_MS / 1000  # where the brake began

    @property
    def slid_estimate_m(self) -> float:
        pose = self.estimator.pose()
        assert pose is not None
        return pose.x - self.brake_x


def test_a_braking_skid_on_a_slope_is_dead_reckoned_with_the_imu():
    skid = _Skid(EstimatorConfig())
    assert skid.true_x - skid.brake_x == pytest.approx(0.125, abs=0.01)
    # 0.100 m of the body's 0.125 m when this was written (the wheels alone: 0.013 m, the next test). The
    # rest is the samples before the slip was told, and the last centimetres/s after the wheels agreed.
    assert 0.09 <= skid.slid_estimate_m <= skid.true_x - skid.brake_x + 0.01
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
