"""A late GPS fix rewinds the filter and re-fuses what came after it (``estimator.history``): what the
filter learnt meanwhile from absolute headings, and a heading given or learnt meanwhile, must survive."""

import math

import pytest

from estimator.config import EstimatorConfig
from estimator.ekf import YAW, RoverEkf
from estimator.estimator import Estimator
from estimator.geodesy import to_geodetic
from estimator.history import FusionHistory, GyroSample, HeadingSample, apply
from logs.clock import SimClock
from logs.sink import MemorySink
from tests.estimator.sim_run import SIM_DATUM

MS = 1_000_000
SPEED_MPS = 0.5
GYRO_BIAS_RPS = 0.05  # the IMU turns the estimate left while the rover drives straight


def _drive(
    *,
    gps_latency_ms: int,
    heading_yaw_rad: float = 0.3,
    attitude_from_ms: int = 0,
    known_heading: bool = True,
    duration_ms: int = 6000,
    yaws: list[float] | None = None,
) -> Estimator:
    """Straight along ``heading_yaw_rad`` at 0.5 m/s for ``duration_ms``: wheels and IMU (gyro biased) at
    50 Hz, AHRS headings at 10 Hz from ``attitude_from_ms`` on, GPS fixes taken at 5 Hz and delivered
    ``gps_latency_ms`` late with their time of fix (the config says the latency too)."""
    config = EstimatorConfig(gps_latency_s=gps_latency_ms / 1000, long_slip_threshold_mps=0.0)
    estimator = Estimator(config, SimClock(), MemorySink())
    if known_heading:
        estimator.set_initial_heading(heading_yaw_rad, 0.05)
    fixes: list[tuple[int, float, float]] = []  # (taken at ms, true east, true north)
    for t in range(0, duration_ms + 1, 20):
        t_ns = t * MS
        travelled = SPEED_MPS * t / 1000
        east, north = travelled * math.cos(heading_yaw_rad), travelled * math.sin(heading_yaw_rad)
        if t % 200 == 0:
            fixes.append((t, east, north))
        while fixes and fixes[0][0] + gps_latency_ms <= t:
            taken, fix_east, fix_north = fixes.pop(0)
            lat, lon, alt = to_geodetic(SIM_DATUM, fix_east, fix_north, 0.0)
            estimator.on_gps(t_ns, lat, lon, alt, 3, 0.05, 12, fix_time_ns=taken * MS)
        if t >= attitude_from_ms and t % 100 == 0:
            estimator.on_attitude(t_ns, heading_yaw_rad, 0.02)
        estimator.on_imu(t_ns, GYRO_BIAS_RPS, 0.0, 0.0)
        # One wheel a side spinning: the odometry's yaw rate is judged poor, the gyro's carries the turn.
        estimator.on_wheel_speeds(
            t_ns, [SPEED_MPS * 1.5, SPEED_MPS, SPEED_MPS, SPEED_MPS * 1.5, SPEED_MPS, SPEED_MPS]
        )
        if yaws is not None and estimator.initialised:
            yaws.append(_yaw(estimator))
    return estimator


def _yaw(estimator: Estimator) -> float:
    pose = estimator.pose()
    assert pose is not None
    return pose.yaw


def test_a_late_fix_keeps_the_heading_updates_made_since_it_was_taken():
    """Rewound to a fix 0.2 s old, the filter must re-fuse the two AHRS headings since, not only the IMU
    and the wheels: then it follows the filter that had each fix on time, step for step."""
    on_time_yaws: list[float] = []
    late_yaws: list[float] = []
    _drive(gps_latency_ms=0, yaws=on_time_yaws)
    late = _drive(gps_latency_ms=200, yaws=late_yaws)
    assert late.counters["gps_fused_late"] > 20
    # The late filter starts 0.2 s later (its first fix arrives then); compare once both have settled.
    settled = list(zip(on_time_yaws[-len(late_yaws) :], late_yaws, strict=True))[150:]
    assert max(abs(on_time - late) for on_time, late in settled) < 4e-5  # 9e-5 when headings were dropped
    assert all(abs(late - 0.3) < 0.001 for _, late in settled)


def test_a_replayed_heading_moves_the_filter_as_its_first_pass_did():
    first, replayed = (RoverEkf(EstimatorConfig()) for _ in range(2))
    for ekf in (first, replayed):
        ekf.initialise(0.0, 0.0, 0.0, 0, position_std_m=0.5, yaw_std_rad=0.1)
        ekf.reset_speed(0.5, 0.05)
    first.acceleration = 0.4
    first.predict(40 * MS)
    first.update_heading(0.05, 0.02)
    apply(replayed, HeadingSample(40 * MS, 0.05, 0.02, acceleration=0.4))
    assert replayed.state_values() == first.state_values()
    assert (replayed.covariance == first.covariance).all()


def test_a_cut_history_cannot_rewind_to_before_the_cut():
    history = FusionHistory(500 * MS)
    ekf = RoverEkf(EstimatorConfig())
    ekf.initialise(0.0, 0.0, 0.0, 0, position_std_m=0.5, yaw_std_rad=0.1)
    for t in (20, 40, 60):
        before = ekf.snapshot()
        apply(ekf, GyroSample(t * MS, 0.0))
        history.record(before, GyroSample(t * MS, 0.0))
    assert history.covers(10 * MS)
    history.cut(60 * MS)
    assert len(history) == 0 and not history.covers(50 * MS)
    assert history.cut_after(50 * MS) and not history.cut_after(60 * MS)


def test_a_heading_given_after_the_first_fix_survives_a_late_fix_taken_before_it():
    """The AHRS comes up 1.1 s after GPS: its first heading replaces the filter's (which knew none).
    The next late fix was taken before that; rewinding to it must not bring the unknown heading back."""
    estimator = _drive(gps_latency_ms=200, heading_yaw_rad=1.2, attitude_from_ms=1100, known_heading=False)
    assert estimator.heading_known
    assert abs(_yaw(estimator) - 1.2) < 0.02
    assert estimator.counters["gps_fused_late"] > 20
    assert estimator.counters["gps_fused_on_arrival"] >= 1  # taken before the heading was given
    assert "gps_too_late" not in estimator.counters


def test_the_fix_right_after_the_heading_is_given_is_fused_on_arrival_not_behind_it():
    """Straight after the heading is given the filter's yaw is the given one, on every later step."""
    config = EstimatorConfig(gps_latency_s=0.2, long_slip_threshold_mps=0.0)
    estimator = Estimator(config, SimClock(), MemorySink())
    for t in range(0, 1001, 20):
        t_ns = t * MS
        if t % 200 == 0 and t >= 200:
            lat, lon, alt = to_geodetic(SIM_DATUM, 0.0, 0.0, 0.0)
            estimator.on_gps(t_ns, lat, lon, alt, 3, 0.05, 12, fix_time_ns=(t - 200) * MS)
        if t == 500:
            estimator.on_attitude(t_ns, -2.0, 0.02)
        estimator.on_imu(t_ns, 0.0, 0.0, 0.0)
        estimator.on_wheel_speeds(t_ns, [0.0] * 6)
        if t >= 500:
            assert estimator._ekf.state(YAW) == pytest.approx(-2.0, abs=1e-6)
