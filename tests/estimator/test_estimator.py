import math

import numpy as np
import pytest

from estimator.config import EstimatorConfig
from estimator.estimator import Estimator
from estimator.geodesy import Datum, to_enu, to_geodetic
from estimator.pose import PoseEstimate
from logs.clock import SimClock
from logs.sink import MemorySink
from logs.topics import ESTIMATOR_INNOVATIONS, ESTIMATOR_POSE, spec
from tests.estimator.rover_sim import Sample, feed, simulate
from tests.estimator.sim_run import SIM_DATUM, Run, S

CONVERGED_S = 20.0


@pytest.mark.parametrize("seed", [11, 12])
def test_converges_in_position_and_heading_without_a_known_heading(seed):
    run = Run()
    run.drive(seed, 100.0, start_yaw=2.0)
    position_rmse, yaw_rmse = run.rmse_after(CONVERGED_S)
    assert position_rmse < 0.5
    assert yaw_rmse < 3.0
    pose = run.estimator.pose()
    assert pose is not None and pose.healthy and pose.heading_known
    assert run.estimator.datum is not None
    assert run.estimator.counters["gps_accepted"] > 400


def test_heading_learnt_when_the_filter_first_settles_the_wrong_way():
    """Facing almost opposite the placeholder heading and turning from the start: the dead-reckoning
    match, not the filter's own linearisation, has to give the heading."""
    run = Run()
    run.drive(1, 60.0, start_yaw=3.1, profile=lambda t: (0.7, 0.3 if t < 30.0 else -0.2))
    assert run.estimator.counters.get("heading_from_motion") == 1
    position_rmse, yaw_rmse = run.rmse_after(CONVERGED_S)
    assert position_rmse < 0.5
    assert yaw_rmse < 3.0


def test_given_heading_is_used_from_the_first_fix():
    run = Run(EstimatorConfig(datum_lat_deg=SIM_DATUM.lat_deg, datum_lon_deg=SIM_DATUM.lon_deg))
    run.estimator.set_initial_heading(-1.0, 0.05)
    run.drive(5, 10.0, start_yaw=-1.0)
    assert run.estimator.heading_known
    assert all(abs(yaw_error) < 5.0 for _, _, yaw_error in run.errors)
    assert "heading_from_motion" not in run.estimator.counters


@pytest.mark.parametrize(
    ("lat", "lon", "fix_type", "eph", "reason"),
    [
        (math.nan, 8.5, 3, 0.5, "gps_not_finite"),
        (47.0, 8.5, 0, 0.5, "gps_no_fix"),
        (95.0, 8.5, 3, 0.5, "gps_out_of_range"),
        (47.0, 8.5, 3, math.inf, "gps_bad_eph"),
    ],
)
def test_bad_fixes_are_rejected_and_counted(lat, lon, fix_type, eph, reason):
    estimator = Estimator(EstimatorConfig(), SimClock(), MemorySink())
    estimator.on_gps(S, lat, lon, 400.0, fix_type, eph, 10)
    assert estimator.counters == {reason: 1}
    assert not estimator.initialised
    assert estimator.datum is None
    assert estimator.pose() is None
    estimator.on_gps(2 * S, 47.0, 8.5, 400.0, 3, None, 10)  # a good one still works afterwards
    assert estimator.initialised
    assert estimator.datum == Datum(47.0, 8.5, 400.0)


def test_bad_imu_and_wheel_samples_are_counted_not_raised():
    run = Run()
    run.drive(3, 5.0)
    run.estimator.on_imu(6 * S, math.nan, 0.0, 0.0)
    run.estimator.on_wheels(6 * S, 1.0, math.inf)
    assert run.estimator.counters["imu_not_finite"] == 1
    assert run.estimator.counters["wheels_not_finite"] == 1


def test_a_50_m_gps_jump_is_gated_out():
    jump_from, jump_to = 40 * S, 41 * S

    def jump(sample: Sample) -> Sample:
        if sample.kind != "gps" or not jump_from <= sample.t_ns < jump_to:
            return sample
        lat, lon, alt, *rest = sample.values
        e, n, u = to_enu(SIM_DATUM, lat, lon, alt)
        return Sample(sample.t_ns, "gps", (*to_geodetic(SIM_DATUM, e + 50.0, n, u), *rest))

    run = Run()
    run.drive(4, 50.0, tamper=jump)
    assert run.estimator.counters["gps_gated"] >= 5
    assert max(err for t, err, _ in run.errors if t >= CONVERGED_S) < 3.0


def test_gps_believed_again_after_a_long_disagreement():
    """A lasting offset means the filter, not GPS, is wrong: after it lasted long enough it re-anchors."""
    config = EstimatorConfig(gps_reset_after_s=2.0)

    def jump(sample: Sample) -> Sample:
        if sample.kind != "gps" or sample.t_ns < 30 * S:
            return sample
        lat, lon, alt, *rest = sample.values
        e, n, u = to_enu(SIM_DATUM, lat, lon, alt)
        return Sample(sample.t_ns, "gps", (*to_geodetic(SIM_DATUM, e, n + 20.0, u), *rest))

    run = Run(config)
    run.drive(6, 40.0, tamper=jump)
    assert run.estimator.counters["gps_reset"] == 1
    assert abs(run.errors[-1][1] - 20.0) < 1.0  # now following the (shifted) GPS


def test_wheel_slip_inflates_odometry_noise_and_heading_holds():
    run = Run()
    run.drive(8, 60.0, wheel_slip_rps=lambda t: 0.4 if 30.0 <= t < 40.0 else 0.0)
    assert run.estimator.counters["odometry_slip"] > 400
    # inflated, the slipping odometry still passes the gate instead of being thrown away wholesale
    assert run.estimator.counters.get("odometry_gated", 0) < 50
    assert max(abs(yaw_error) for t, _, yaw_error in run.errors if t >= CONVERGED_S) < 5.0


def test_one_innovation_message_per_update_and_pose_layout():
    run = Run()
    assert run.estimator.publish_pose(0) is False
    run.drive(9, 5.0)
    counters = run.estimator.counters
    updates = sum(v for k, v in counters.items() if k.endswith(("_accepted", "_gated")))
    innovations = run.sink.on(ESTIMATOR_INNOVATIONS)
    assert len(innovations) == updates
    assert set(innovations[0]) == set(spec(ESTIMATOR_INNOVATIONS).schema["required"])
    assert {m["sensor"] for m in innovations} == {"gps", "gyro", "odometry"}

    assert run.estimator.publish_pose(run.clock.now_ns() + 10_000_000)
    topic, log_time, message = run.sink.records[-1]
    assert topic == ESTIMATOR_POSE and log_time == run.clock.now_ns()
    assert set(message) == set(spec(ESTIMATOR_POSE).schema["required"])
    assert len(message["covariance"]) == 49 and len(message["state_names"]) == 7
    assert message["timestamp"] == {"sec": 5, "nsec": 10_000_000}
    assert message["frame_id"] == "enu"


def test_pose_extrapolation_does_not_change_the_filter():
    run = Run()
    run.drive(10, 5.0)
    now = run.estimator.pose()
    ahead = run.estimator.pose(now.t_ns + S)
    again = run.estimator.pose()
    assert ahead.t_ns == now.t_ns + S
    assert math.hypot(ahead.x - now.x, ahead.y - now.y) == pytest.approx(abs(now.speed), rel=0.05)
    assert (again.x, again.y, again.yaw, again.t_ns) == (now.x, now.y, now.yaw, now.t_ns)
    assert np.array_equal(again.covariance, now.covariance)
    # Asked for a time not after the filter's own: the last answer itself; a later time: extrapolated.
    assert run.estimator.pose(again.t_ns) is again and run.estimator.pose(again.t_ns - 1) is again
    assert run.estimator.pose(again.t_ns + 1).t_ns == again.t_ns + 1


def test_a_pose_asked_again_is_reused_only_while_nothing_was_fused():
    """``pose()`` hands out its last answer again while the filter is unchanged: after every sample
    (accepted, gated or refused) the pose must still be what the filter holds now."""
    run = Run()
    run.estimator.on_attitude(0, 0.3, 0.1)  # before the first fix: a refused-then-used heading as well
    reused = 0
    for truth, samples in simulate(np.random.default_rng(4), SIM_DATUM, 12.0):
        run.clock.advance(truth.t_ns - run.clock.now_ns())
        for sample in samples:
            before = run.estimator.pose()
            feed(run.estimator, [sample])
            pose = run.estimator.pose()
            if pose is None:
                continue
            ekf = run.estimator._ekf  # the reference: the filter itself, read directly
            assert (pose.x, pose.y, pose.yaw, pose.speed, pose.yaw_rate) == tuple(ekf.x[:5].tolist())
            assert np.array_equal(pose.covariance, ekf.covariance) and pose.t_ns == ekf.t_ns
            health = run.estimator.health()
            assert (pose.healthy, pose.position_std_m) == (health.healthy, health.position_std_m)
            assert pose.heading_known == run.estimator.heading_known
            assert run.estimator.pose() is pose and not pose.covariance.flags.writeable
            reused += pose is before
    assert reused == 0  # every sample of this drive changed the filter: no stale pose was handed out


def test_same_inputs_same_messages():
    first, second = Run(), Run()
    first.drive(21, 15.0)
    second.drive(21, 15.0)
    assert first.sink.records == second.sink.records
    assert first.estimator.counters == second.estimator.counters


def test_pose_estimate_is_equal_only_to_itself_and_immutable():
    """A NamedTuple for speed, compared as the frozen dataclass with eq=False was: by identity, never by
    tuple equality (elementwise over the covariance array, which would raise)."""
    covariance = np.eye(7)
    first = PoseEstimate(1.0, 2.0, 0.5, 0.3, 0.0, covariance, True, 10, True, 0.1)
    same_values = PoseEstimate(1.0, 2.0, 0.5, 0.3, 0.0, covariance, True, 10, True, 0.1)
    assert first == first and first != same_values
    assert len({first, same_values}) == 2
    with pytest.raises(AttributeError):
        first.x = 3.0
