"""GPS glitches, dropouts, spinning wheels and late fixes, on the seeded estimator-level simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimator.config import EstimatorConfig
from navigator.follower import FollowerConfig, PurePursuit
from tests.estimator.rover_sim import GROUND, Truth
from tests.estimator.sim_run import SIM_DATUM, Run, Step

S = 1_000_000_000
AT_SIM_DATUM = EstimatorConfig(
    datum_lat_deg=SIM_DATUM.lat_deg, datum_lon_deg=SIM_DATUM.lon_deg, datum_alt_m=SIM_DATUM.alt_m
)


def _run(config: EstimatorConfig = AT_SIM_DATUM) -> Run:
    run = Run(config)
    run.estimator.set_initial_heading(2.0, 0.1)
    return run


def _at(run: Run, t_s: float) -> Step:
    return min(run.steps, key=lambda step: abs(step.t_s - t_s))


# --- a 50 m GPS step glitch for 5 s ------------------------------------------------------------------
GLITCH_FROM_S, GLITCH_TO_S = 40.0, 45.0


def _glitch(t_s: float) -> tuple[float, float]:
    return (50.0, 0.0) if GLITCH_FROM_S <= t_s < GLITCH_TO_S else (0.0, 0.0)


def _follower_commands(run: Run, path: np.ndarray) -> list[tuple[float, float, float]]:
    """(t_s, speed, yaw rate) the pure-pursuit follower commands from each estimate, along ``path``."""
    follower = PurePursuit(FollowerConfig())
    commands = []
    for step in run.steps:
        pose = step.pose
        command = follower.command(pose.x, pose.y, pose.yaw, pose.speed, path)
        commands.append((step.t_s, command.speed_mps, command.yaw_rate_rps))
    return commands


@pytest.fixture(scope="module")
def glitch_runs() -> tuple[Run, Run]:
    clean, glitched = _run(), _run()
    clean.drive(4, 60.0)
    glitched.drive(4, 60.0, gps_offset_m=_glitch)
    return clean, glitched


def test_glitch_fixes_are_all_rejected_and_no_reset(glitch_runs):
    _, glitched = glitch_runs
    counters = glitched.estimator.counters
    assert counters["gps_gated"] == 25  # 5 s at 5 Hz, every one of them
    assert "gps_reset" not in counters


def test_glitch_estimate_stays_within_3_m_of_truth(glitch_runs):
    _, glitched = glitch_runs
    during = [s.position_error_m for s in glitched.steps if GLITCH_FROM_S <= s.t_s < GLITCH_TO_S + 5.0]
    assert max(during) < 3.0
    assert max(s.position_error_m for s in glitched.steps if s.t_s > 5.0) < 3.0


def test_glitch_leaves_no_jump_in_the_follower_output(glitch_runs):
    clean, glitched = glitch_runs
    # A path along the true track (in the estimator's frame), as the planner would have laid it.
    path = np.array([(s.true_x, s.true_y) for s in clean.steps[::25]])
    reference = _follower_commands(clean, path)
    commands = _follower_commands(glitched, path)
    window = [i for i, (t, _, _) in enumerate(commands) if GLITCH_FROM_S - 1.0 <= t < GLITCH_TO_S + 2.0]
    # Same commands as without the glitch (only 25 fixes' worth of information is missing) ...
    assert max(abs(commands[i][2] - reference[i][2]) for i in window) < 0.1
    assert max(abs(commands[i][1] - reference[i][1]) for i in window) < 0.05
    # ... and no step change from one control step to the next beyond what the clean run shows.
    steps = [abs(commands[i][2] - commands[i - 1][2]) for i in window]
    clean_steps = [abs(reference[i][2] - reference[i - 1][2]) for i in window]
    assert max(steps) < max(clean_steps) + 0.05


def test_a_persistent_offset_gets_exactly_one_logged_reset(caplog):
    run = _run(EstimatorConfig(**{**AT_SIM_DATUM.__dict__, "gps_reset_after_s": 8.0}))
    with caplog.at_level("WARNING", logger="estimator.estimator"):
        run.drive(6, 60.0, gps_offset_m=lambda t: (0.0, 20.0) if t >= 30.0 else (0.0, 0.0))
    assert run.estimator.counters["gps_reset"] == 1
    assert any("re-anchored on GPS" in r.getMessage() for r in caplog.records)
    assert abs(run.steps[-1].position_error_m - 20.0) < 1.0  # now following the (shifted) GPS


# --- a 30 s GPS dropout on rocky ground ------------------------------------------------------------
DROPOUT_FROM_S, DROPOUT_TO_S = 85.0, 115.0


def _no_gps_during_dropout(t_s: float) -> bool:
    return not DROPOUT_FROM_S <= t_s < DROPOUT_TO_S


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_dropout_on_rocky_ground_drifts_at_most_3_percent(seed):
    run = _run()
    run.drive(seed, DROPOUT_TO_S, ground=GROUND["rocky"], gps_available=_no_gps_during_dropout)
    start, end = _at(run, DROPOUT_FROM_S), run.steps[-1]
    travelled = end.truth.distance - start.truth.distance
    assert travelled > 20.0
    assert end.position_error_m <= 0.03 * travelled
    # dead reckoning is not pretended to be as good as GPS: the covariance grew meanwhile
    assert end.pose.position_std_m > 2.0 * start.pose.position_std_m


def test_dropout_turns_health_flags_when_the_covariance_passes_its_threshold():
    limit = 0.18  # m: above the GPS-aided std here (<= 0.1 m), below where 30 s of dead reckoning ends
    run = _run(EstimatorConfig(**{**AT_SIM_DATUM.__dict__, "healthy_position_std_m": limit}))
    health_at: dict[float, tuple[bool, bool, float]] = {}

    def record(truth: Truth) -> None:
        health = run.estimator.health()
        health_at[round(truth.t_ns / S, 2)] = (health.healthy, health.gps_fresh, health.position_std_m)

    run.drive(1, 125.0, ground=GROUND["rocky"], gps_available=_no_gps_during_dropout, on_step=record)
    for t, (healthy, _, std) in health_at.items():
        if t > 5.0:
            assert healthy == (std < limit), f"t={t}: healthy={healthy} with position std {std:.3f} m"
    assert health_at[80.0][0] and health_at[80.0][1]
    assert not health_at[114.98][0]  # dead reckoning for 30 s: std past the limit
    assert not health_at[90.0][1]  # no accepted fix for 5 s: GPS not fresh
    assert health_at[124.0][0] and health_at[124.0][1]  # GPS back: healthy again
    assert any(not healthy for t, (healthy, _, _) in health_at.items() if DROPOUT_FROM_S < t < DROPOUT_TO_S)
    assert run.estimator.counters.get("gps_reset", 0) == 0  # reacquired through the gate, no reset


# --- wheels spinning in place ---------------------------------------------------------------------
def test_stuck_rover_with_spinning_wheels_believes_gps_not_odometry():
    """Pushing against a rock for 10 s: wheels report 1 m/s, the body stands still."""
    run = _run()
    stuck = (30.0, 40.0)
    run.drive(
        7, 50.0, profile=lambda t: (1.0, 0.0), ground_share=lambda t: 0.0 if stuck[0] <= t < stuck[1] else 1.0
    )
    counters = run.estimator.counters
    assert counters["odometry_spinning_on"] >= 1
    assert counters["odometry_speed_left_out"] > 200  # most of the 10 s
    assert counters.get("gps_gated", 0) < 10
    assert "gps_reset" not in counters
    # Judging takes a GPS window (~2.5 s at 0.5 m noise); after that GPS, not odometry, holds the position.
    assert max(s.position_error_m for s in run.steps if s.t_s >= 10.0) < 2.5
    assert max(s.position_error_m for s in run.steps if s.t_s >= stuck[0] + 3.0) < 1.0  # GPS-only
    assert np.mean([abs(s.pose.speed) for s in run.steps if stuck[0] + 3.0 <= s.t_s < stuck[1]]) < 0.3
    assert run.estimator.health().odometry_trusted  # grip again after the push


# --- late fixes -------------------------------------------------------------------------------------
@pytest.mark.parametrize("latency_steps", [10])
def test_late_fixes_are_fused_at_their_own_time(latency_steps):
    """Fixes delivered 200 ms late: fused on arrival they lag the track; fused at their time they don't."""
    latency_s = latency_steps * 0.02
    config = EstimatorConfig(**{**AT_SIM_DATUM.__dict__, "gps_latency_s": latency_s})
    late_aware, naive = _run(config), _run()
    late_aware.drive(9, 60.0, gps_latency_steps=latency_steps)
    naive.drive(9, 60.0, gps_latency_steps=latency_steps)
    assert late_aware.estimator.counters["gps_fused_late"] > 250
    aware_rmse, _ = late_aware.rmse_after(10.0)
    naive_rmse, _ = naive.rmse_after(10.0)
    assert aware_rmse < 0.25
    assert aware_rmse < 0.8 * naive_rmse


def test_a_fix_older_than_the_history_is_counted_not_fused():
    config = EstimatorConfig(**{**AT_SIM_DATUM.__dict__, "gps_latency_s": 0.1})
    run = _run(config)
    run.drive(2, 5.0, gps_available=lambda t: t < 2.0)
    before = run.estimator.pose()
    run.estimator.on_gps(5 * S, SIM_DATUM.lat_deg, SIM_DATUM.lon_deg, 408.0, 3, 0.5, 10, fix_time_ns=3 * S)
    assert run.estimator.counters["gps_too_late"] == 1
    after = run.estimator.pose()
    assert (after.x, after.y) == (before.x, before.y)


# --- bad samples ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("call", "reason"),
    [
        (lambda e: e.on_imu(6 * S, 40.0, 0.0, 0.0), "imu_out_of_range"),
        (lambda e: e.on_imu(6 * S, 0.1, 500.0, 0.0), "imu_out_of_range"),
        (lambda e: e.on_imu(6 * S, 0.1, math.nan, 0.0), "imu_not_finite"),
        (lambda e: e.on_imu(1 * S, 0.1, 0.0, 0.0), "imu_stale"),
        (lambda e: e.on_wheels(6 * S, 1.0, 35.0), "wheels_out_of_range"),
        (lambda e: e.on_wheels(1 * S, 1.0, 1.0), "wheels_stale"),
        (lambda e: e.on_wheel_speeds(6 * S, [1.0] * 5), "wheels_malformed"),
        (lambda e: e.on_wheel_speeds(6 * S, [1.0] * 5 + [math.nan]), "wheels_not_finite"),
        (lambda e: e.on_wheel_speeds(6 * S, [1.0] * 5 + [-99.0]), "wheels_out_of_range"),
        (lambda e: e.on_gps(6 * S, 47.0, 200.0, 400.0, 3, 0.5, 9), "gps_out_of_range"),
        (lambda e: e.on_gps(6 * S, 47.0, 8.5, 400.0, 1, 0.5, 2), "gps_no_fix"),
        (lambda e: e.on_gps(6 * S, math.inf, 8.5, 400.0, 3, 0.5, 9), "gps_not_finite"),
        (lambda e: e.on_gps(4 * S, 47.0, 8.5, 400.0, 3, 0.5, 9), "gps_out_of_order"),
    ],
)
def test_bad_samples_are_rejected_counted_and_change_nothing(call, reason):
    run = _run()
    run.drive(3, 5.0)
    estimator = run.estimator
    before, counters = estimator.pose(), estimator.counters
    call(estimator)
    after = estimator.counters
    assert after[reason] == counters.get(reason, 0) + 1
    assert sum(after.values()) == sum(counters.values()) + 1
    pose = estimator.pose()
    assert (pose.x, pose.y, pose.yaw, pose.t_ns) == (before.x, before.y, before.yaw, before.t_ns)


def test_six_wheel_spread_inflates_the_odometry_noise():
    run = _run()
    run.drive(3, 5.0)
    estimator = run.estimator
    t = 5 * S + 20_000_000
    estimator.on_wheel_speeds(t, [1.0, 1.0, 1.0, 1.0, 1.0, 1.0])
    assert "odometry_wheel_spread" not in estimator.counters
    estimator.on_wheel_speeds(t + 20_000_000, [1.0, 1.6, 1.0, 1.0, 1.0, 1.0])
    assert estimator.counters["odometry_wheel_spread"] == 1


# --- AHRS heading ---------------------------------------------------------------------------------
def test_attitude_headings_are_fused_gated_and_first_one_initialises():
    run = Run(AT_SIM_DATUM)
    rng = np.random.default_rng(5)
    yaw0 = 2.0
    run.estimator.on_attitude(0, yaw0 + 0.08, math.radians(5.0))  # a first sample 4.6 deg off
    assert run.estimator.heading_known

    def attitude(truth: Truth) -> None:
        if truth.t_ns % 100_000_000 == 0:  # 10 Hz AHRS, 2 deg noise
            run.estimator.on_attitude(
                truth.t_ns, truth.yaw + float(rng.normal(0.0, 0.035)), math.radians(5.0)
            )

    run.drive(12, 30.0, start_yaw=yaw0, on_step=attitude)
    counters = run.estimator.counters
    assert counters["heading_accepted"] > 250
    _, yaw_rmse = run.rmse_after(5.0)
    assert yaw_rmse < 1.0
    run.estimator.on_attitude(run.steps[-1].truth.t_ns, run.steps[-1].truth.yaw + 2.0, math.radians(5.0))
    assert run.estimator.counters["heading_gated"] == counters.get("heading_gated", 0) + 1
    run.estimator.on_attitude(run.steps[-1].truth.t_ns, math.nan, 0.1)
    assert run.estimator.counters["attitude_not_finite"] == 1
