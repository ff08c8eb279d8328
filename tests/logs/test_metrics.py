"""Trial metrics on small hand-computable recordings."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from logs.clock import to_ns
from logs.metrics import TrialMetrics, compute_metrics, distances_to_polyline, planned_route
from logs.recorder import McapRecorder
from logs.topics import (
    ESTIMATOR_POSE,
    NAVIGATOR_PATH,
    NAVIGATOR_STATE,
    TRUTH_CONTACTS,
    TRUTH_POSE,
    WHEELS_STATUS,
    planar_pose,
    stamp,
)

# One sample per second. Segments 3..6 leave the straight path y=0 by 1-2 m (off, tolerance 0.5):
#   on:  (0,0)-(1,0)-(2,0)-(3,0)                  3 m
#   off: (3,0)-(3,2)-(4,2)-(5,2)-(5,0)            2+1+1+2 = 6 m (midpoints 1 m or 2 m from the path)
#   on:  (5,0)-(6,0)-...-(10,0)                   5 m
# => path accuracy = 100 * 8 / 14 %.
TRAJECTORY = [(0, 0), (1, 0), (2, 0), (3, 0), (3, 2), (4, 2), (5, 2), (5, 0)] + [(x, 0) for x in range(6, 11)]
OBSTACLES = [
    {"id": "A", "x": 4.0, "y": 5.0, "radius": 0.5},  # 3 m from (4,2): beyond 0.5+1.5, not encountered
    {"id": "B", "x": 8.0, "y": 1.0, "radius": 0.5},  # 1 m away: encountered, and hit (collision below)
    {"id": 7, "x": 9.0, "y": -1.2, "radius": 0.3},  # 1.2 m away: encountered, avoided
]


def _pose(t_ns: int, x: float, y: float) -> dict:
    return {"timestamp": stamp(t_ns), "frame_id": "enu", "pose": planar_pose(x, y, 0.0)}


def _path(t_ns: int, points: list[tuple[float, float]]) -> dict:
    poses = [planar_pose(x, y, 0.0) for x, y in points]
    return {"timestamp": stamp(t_ns), "frame_id": "enu", "poses": poses, "cost": 1.0, "length_m": 10.0}


def _state(t_ns: int, mode: str, xte: float, goal: tuple[float, float] | None = (10.0, 0.5)) -> dict:
    return {
        "timestamp": stamp(t_ns),
        "mode": mode,
        "goal": None if goal is None else {"x": goal[0], "y": goal[1]},
        "cross_track_error_m": xte,
    }


def _wheels(t_ns: int, current_a: float) -> dict:
    wheel = {"input_voltage_v": 24.0, "input_current_a": current_a}
    return {"timestamp": stamp(t_ns), "wheels": [dict(wheel) for _ in range(6)]}


def _contact(t_ns: int, kind: str, obstacle_id: str) -> dict:
    return {"timestamp": stamp(t_ns), "kind": kind, "obstacle_id": obstacle_id, "x": 0.0, "y": 0.0}


def _sim_trial(pose_topic: str = TRUTH_POSE, scenario: dict[str, str] | None = None) -> bytes:
    buffer = io.BytesIO()
    with McapRecorder(buffer, chunk_size=2048) as rec:
        rec.add_metadata(
            "scenario",
            scenario
            if scenario is not None
            else {"path_tolerance_m": "0.5", "obstacles_json": json.dumps(OBSTACLES)},
        )
        rec.publish(NAVIGATOR_PATH, 0, _path(0, [(0.0, 0.0), (10.0, 0.0)]))
        for i, (x, y) in enumerate(TRAJECTORY):
            t = to_ns(float(i))
            rec.publish(pose_topic, t, _pose(t, x, y))
            if i < 3:
                rec.publish(WHEELS_STATUS, t, _wheels(t, 1.0 if i < 2 else 2.0))
        rec.publish(NAVIGATOR_STATE, to_ns(1.0), _state(to_ns(1.0), "DRIVING", 0.3))
        rec.publish(NAVIGATOR_STATE, to_ns(5.0), _state(to_ns(5.0), "DRIVING", -0.4))
        rec.publish(NAVIGATOR_STATE, to_ns(12.0), _state(to_ns(12.0), "ARRIVED", 0.0))
        contact = {
            "timestamp": stamp(to_ns(9.0)),
            "kind": "collision",
            "obstacle_id": "B",
            "x": 8.0,
            "y": 0.6,
        }
        rec.publish(TRUTH_CONTACTS, to_ns(9.0), contact)
        rollover = {
            "timestamp": stamp(to_ns(10.0)),
            "kind": "rollover",
            "obstacle_id": "",
            "x": 9.0,
            "y": 0.0,
        }
        rec.publish(TRUTH_CONTACTS, to_ns(10.0), rollover)
    return buffer.getvalue()


def test_hand_computed_metrics() -> None:
    metrics = compute_metrics(io.BytesIO(_sim_trial()))
    assert metrics.trajectory_topic == TRUTH_POSE
    assert metrics.distance_m == pytest.approx(14.0)
    assert metrics.duration_s == pytest.approx(12.0)
    assert metrics.path_tolerance_m == 0.5
    assert metrics.path_accuracy_pct == pytest.approx(100.0 * 8.0 / 14.0)
    # The route (10 m) is passed within 0.5 m except for x in (3.5, 4.5), where the detour ran 2 m off.
    assert metrics.route_length_m == pytest.approx(10.0)
    assert metrics.route_accuracy_pct == pytest.approx(90.0)
    assert (metrics.obstacles_encountered, metrics.obstacles_avoided) == (2, 1)
    assert metrics.obstacle_avoidance_success_pct == pytest.approx(50.0)
    assert (metrics.collisions, metrics.rollovers) == (1, 1)
    # 6 wheels x 24 V x (1, 1, 2) A at t = 0, 1, 2 s: trapezoid 144 J + 216 J = 360 J = 0.1 Wh
    assert metrics.energy_wh == pytest.approx(0.1)
    assert metrics.energy_wh_per_m == pytest.approx(0.1 / 14.0)
    assert metrics.goal_reached is True
    assert metrics.final_distance_to_goal_m == pytest.approx(0.5)
    assert metrics.cross_track_error_rms_m == pytest.approx(math.sqrt(0.25 / 3.0))
    assert metrics.cross_track_error_max_m == pytest.approx(0.4)
    assert metrics.missing == () and metrics.problems == ()
    assert not metrics.truncated


def _parked_after_arrival(last_mode: str) -> bytes:
    """Drives x = 0..10 m in 10 s (an intermediate goal reached at 5 s), then stands at (10, 0) to 20 s."""
    buffer = io.BytesIO()
    with McapRecorder(buffer) as rec:
        rec.add_metadata("scenario", {"path_tolerance_m": "0.5", "obstacles_json": "[]"})
        rec.publish(NAVIGATOR_PATH, 0, _path(0, [(0.0, 0.0), (10.0, 0.0)]))
        for second in range(21):
            t = to_ns(float(second))
            rec.publish(TRUTH_POSE, t, _pose(t, float(min(second, 10)), 0.0))
        states = [(1, "DRIVING", 0.3), (5, "ARRIVED", 0.0), (6, "DRIVING", -0.4), (10, "ARRIVED", 0.0)]
        states += [(second, "ARRIVED", 0.0) for second in range(11, 20)] + [(20, last_mode, 0.0)]
        for second, mode, xte in states:
            t = to_ns(float(second))
            rec.publish(NAVIGATOR_STATE, t, _state(t, mode, xte))
    return buffer.getvalue()


def test_time_standing_at_the_goal_after_the_last_arrival_is_not_part_of_the_drive() -> None:
    metrics = compute_metrics(io.BytesIO(_parked_after_arrival("ARRIVED")))
    assert metrics.duration_s == pytest.approx(10.0)
    assert metrics.cross_track_error_rms_m == pytest.approx(math.sqrt(0.25 / 4.0))
    assert metrics.distance_m == pytest.approx(10.0) and metrics.goal_reached is True


def test_a_recording_that_does_not_end_arrived_is_a_drive_to_its_end() -> None:
    metrics = compute_metrics(io.BytesIO(_parked_after_arrival("DRIVING")))
    assert metrics.duration_s == pytest.approx(20.0)
    assert metrics.cross_track_error_rms_m == pytest.approx(math.sqrt(0.25 / 14.0))
    assert metrics.goal_reached is False


def test_tolerance_from_metadata_changes_the_share() -> None:
    scenario = {"path_tolerance_m": "1.5", "obstacles_json": "[]"}
    metrics = compute_metrics(io.BytesIO(_sim_trial(scenario=scenario)))
    # midpoints 1 m off now count (3,1) and (5,1): 2 + 2 m more within => 12 / 14
    assert metrics.path_accuracy_pct == pytest.approx(100.0 * 12.0 / 14.0)
    assert metrics.obstacles_encountered == 0 and metrics.obstacle_avoidance_success_pct is None


def test_the_path_in_force_is_the_latest_at_or_before_each_sample() -> None:
    buffer = io.BytesIO()
    with McapRecorder(buffer) as rec:
        rec.publish(NAVIGATOR_PATH, 0, _path(0, [(0.0, 0.0), (10.0, 0.0)]))
        rec.publish(NAVIGATOR_PATH, to_ns(2.0), _path(to_ns(2.0), [(0.0, 3.0), (10.0, 3.0)]))
        for i in range(4):
            rec.publish(TRUTH_POSE, to_ns(float(i)), _pose(to_ns(float(i)), float(i), 0.0))
    metrics = compute_metrics(io.BytesIO(buffer.getvalue()))
    # segment ending at t=1 s follows path 1 (on); those ending at t=2 s and t=3 s follow path 2 (3 m off)
    assert metrics.path_accuracy_pct == pytest.approx(100.0 / 3.0)


def test_real_run_falls_back_to_estimator_pose_and_lists_missing_data() -> None:
    buffer = io.BytesIO()
    with McapRecorder(buffer) as rec:
        for i, (x, y) in enumerate([(0.0, 0.0), (3.0, 4.0)]):
            rec.publish(ESTIMATOR_POSE, to_ns(float(i)), _pose(to_ns(float(i)), x, y))
    metrics = compute_metrics(io.BytesIO(buffer.getvalue()))
    assert metrics.trajectory_topic == ESTIMATOR_POSE
    assert metrics.distance_m == pytest.approx(5.0)
    assert metrics.path_accuracy_pct is None and metrics.energy_wh is None and metrics.goal_reached is None
    assert metrics.collisions is None and metrics.rollovers is None
    assert set(metrics.missing) == {
        "metadata:scenario",
        "metadata:scenario.obstacles_json",
        NAVIGATOR_PATH,
        TRUTH_CONTACTS,
        WHEELS_STATUS,
        NAVIGATOR_STATE,
    }


def test_empty_recording_gives_all_none_without_raising() -> None:
    buffer = io.BytesIO()
    McapRecorder(buffer).close()
    metrics = compute_metrics(io.BytesIO(buffer.getvalue()))
    assert metrics.trajectory_topic is None and metrics.distance_m is None and metrics.duration_s is None
    assert f"{TRUTH_POSE} or {ESTIMATOR_POSE}" in metrics.missing


def test_simulation_without_contacts_counts_zero() -> None:
    buffer = io.BytesIO()
    with McapRecorder(buffer) as rec:
        rec.publish(TRUTH_POSE, 0, _pose(0, 0.0, 0.0))
    metrics = compute_metrics(io.BytesIO(buffer.getvalue()))
    assert (metrics.collisions, metrics.rollovers) == (0, 0)
    assert TRUTH_CONTACTS not in metrics.missing


def test_bad_values_are_reported_not_raised() -> None:
    scenario = {"path_tolerance_m": "-3", "obstacles_json": "{oops"}
    buffer = io.BytesIO(_sim_trial(scenario=scenario))
    metrics = compute_metrics(buffer)
    assert metrics.path_tolerance_m == 0.5  # fell back to the default
    assert metrics.obstacles_encountered is not None and metrics.obstacles_encountered == 0
    assert any("path_tolerance_m" in p for p in metrics.problems)
    assert any("obstacles_json" in p for p in metrics.problems)


def test_to_dict_rounds_and_write_json_is_stable(tmp_path: Path) -> None:
    data = _sim_trial()
    metrics = compute_metrics(io.BytesIO(data))
    as_dict = metrics.to_dict()
    assert as_dict["path_accuracy_pct"] == round(100.0 * 8.0 / 14.0, 6)
    assert as_dict["missing"] == []
    first, second = tmp_path / "a" / "m.json", tmp_path / "b.json"
    metrics.write_json(first)
    compute_metrics(io.BytesIO(data)).write_json(second)
    assert first.read_bytes() == second.read_bytes()
    assert json.loads(first.read_text())["collisions"] == 1
    assert isinstance(metrics, TrialMetrics)


def test_metrics_from_a_file_path(tmp_path: Path) -> None:
    path = tmp_path / "trial.mcap"
    path.write_bytes(_sim_trial())
    assert compute_metrics(path) == compute_metrics(io.BytesIO(_sim_trial()))


def test_distances_to_polyline() -> None:
    import numpy as np

    polyline = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    points = np.array([[5.0, 2.0], [-3.0, 4.0], [12.0, 5.0], [10.0, 10.0]])
    assert distances_to_polyline(points, polyline) == pytest.approx([2.0, 5.0, 2.0, 0.0])
    assert distances_to_polyline(points[:1], polyline[:1]) == pytest.approx([math.hypot(5.0, 2.0)])


def test_cut_recording_is_flagged() -> None:
    data = _sim_trial()
    metrics = compute_metrics(io.BytesIO(data[: len(data) // 4]))  # the summary is the latter half
    assert metrics.truncated
    assert any("cut short" in p for p in metrics.problems)


def _route_trial(
    paths: list[tuple[float, list[tuple[float, float]]]], trajectory: list[tuple[float, float]]
) -> bytes:
    buffer = io.BytesIO()
    with McapRecorder(buffer) as rec:
        rec.add_metadata("scenario", {"path_tolerance_m": "0.5", "obstacles_json": "[]"})
        for t_s, points in paths:
            rec.publish(NAVIGATOR_PATH, to_ns(t_s), _path(to_ns(t_s), points))
        for i, (x, y) in enumerate(trajectory):
            rec.publish(TRUTH_POSE, to_ns(float(i)), _pose(to_ns(float(i)), x, y))
    return buffer.getvalue()


def test_a_run_cut_short_scores_only_the_route_it_drove() -> None:
    # A rollover 2 m along a 10 m route: on the path all the way (path accuracy 100 %), but only the first
    # 2.5 m of the route (2 m driven + the 0.5 m tolerance) were passed.
    trial = _route_trial([(0.0, [(0.0, 0.0), (10.0, 0.0)])], [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0)])
    metrics = compute_metrics(io.BytesIO(trial))
    assert metrics.path_accuracy_pct == pytest.approx(100.0)
    assert metrics.route_length_m == pytest.approx(10.0)
    assert metrics.route_accuracy_pct == pytest.approx(25.0)


def test_a_replan_replaces_the_rest_of_the_old_plan_in_the_route() -> None:
    # At t = 3 s the rover, at (3, 0), replans round something ahead: the route is the old plan up to
    # (3, 0) (3 m) and the new plan (2 + 7 m); the rover drives exactly that.
    paths = [(0.0, [(0.0, 0.0), (10.0, 0.0)]), (3.0, [(3.0, 0.0), (3.0, 2.0), (10.0, 2.0)])]
    trajectory = [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0), (3.0, 1.0), (3.0, 2.0)]
    trajectory += [(float(x), 2.0) for x in range(4, 11)]
    metrics = compute_metrics(io.BytesIO(_route_trial(paths, trajectory)))
    assert metrics.route_length_m == pytest.approx(12.0)
    assert metrics.route_accuracy_pct == pytest.approx(100.0)
    # A rover that kept to the old line instead passes only the 3 m shared start and the first 0.5 m of
    # the new plan's first leg (within 0.5 m of the old line).
    straight = [(float(x), 0.0) for x in range(11)]
    metrics = compute_metrics(io.BytesIO(_route_trial(paths, straight)))
    assert metrics.route_accuracy_pct == pytest.approx(100.0 * 3.5 / 12.0)


def test_planned_route_cuts_each_plan_where_the_next_begins() -> None:
    first = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0]])
    second = np.array([[4.5, 2.0], [8.0, 2.0]])  # began 0.5 m beside the first plan's second leg
    route = planned_route([first, np.zeros((0, 2)), second])
    assert len(route) == 2
    np.testing.assert_allclose(route[0], [[0.0, 0.0], [4.0, 0.0], [4.0, 2.0]])
    np.testing.assert_allclose(route[1], second)
    assert planned_route([]) == []


def test_near_polyline_agrees_with_the_exact_distances():
    from logs.metrics import distances_to_polyline, near_polyline

    rng = np.random.default_rng(11)
    for trial in range(60):
        # Dense wiggly trajectories and sparse long-segment paths, with points straddling the radius.
        vertices = int(rng.integers(1, 400))
        step = 0.02 if trial % 2 else 3.0
        polyline = np.cumsum(rng.normal(0.0, step, (vertices, 2)), axis=0)
        points = polyline[rng.integers(0, vertices, 300)] + rng.normal(0.0, 0.6, (300, 2))
        radius = float(rng.uniform(0.05, 0.8))
        exact = distances_to_polyline(points, polyline) <= radius
        assert np.array_equal(near_polyline(points, polyline, radius), exact)
    assert near_polyline(np.zeros((0, 2)), np.zeros((3, 2)), 0.5).shape == (0,)


def test_estimated_poses_count_only_when_they_are_the_trajectory() -> None:
    """A simulated trial's estimated poses are not used (the truth is): a broken one is not the metrics'
    concern. A real run's are the trajectory: a broken one is skipped and counted."""

    def recording(with_truth: bool) -> io.BytesIO:
        buffer = io.BytesIO()
        with McapRecorder(buffer) as rec:
            for i, (x, y) in enumerate([(0.0, 0.0), (3.0, 4.0), (6.0, 8.0)]):
                t_ns = to_ns(float(i))
                if with_truth:
                    rec.publish(TRUTH_POSE, t_ns, _pose(t_ns, x, y))
                rec.publish(ESTIMATOR_POSE, t_ns, _pose(t_ns, x, y))
            rec.publish_bytes(ESTIMATOR_POSE, to_ns(3.0), b"[1, 2]")  # JSON, but not an object
            rec.publish(ESTIMATOR_POSE, to_ns(4.0), {"timestamp": stamp(to_ns(4.0)), "pose": {}})
        return io.BytesIO(buffer.getvalue())

    simulated = compute_metrics(recording(with_truth=True))
    assert simulated.trajectory_topic == TRUTH_POSE and simulated.distance_m == pytest.approx(10.0)
    assert simulated.skipped_messages == 0
    assert not any(ESTIMATOR_POSE in problem for problem in simulated.problems)

    real = compute_metrics(recording(with_truth=False))
    assert real.trajectory_topic == ESTIMATOR_POSE and real.distance_m == pytest.approx(10.0)
    assert real.skipped_messages == 2
    assert f"{ESTIMATOR_POSE}: 2 message(s) without usable values skipped" in real.problems


def test_wheel_power_with_a_non_finite_value_is_skipped() -> None:
    buffer = io.BytesIO()
    with McapRecorder(buffer) as rec:
        for i, current in enumerate([1.0, 0.0, 2.0, math.nan, 3.0]):
            t_ns = to_ns(float(i))
            rec.publish(TRUTH_POSE, t_ns, _pose(t_ns, float(i), 0.0))
            status = _wheels(t_ns, current)
            if i == 1:
                status["wheels"][0]["input_voltage_v"] = math.inf  # inf V x 0 A: the product is NaN
            rec.publish_bytes(WHEELS_STATUS, t_ns, json.dumps(status).encode())
    metrics = compute_metrics(io.BytesIO(buffer.getvalue()))
    assert metrics.skipped_messages == 2
    # the usable samples: 6 wheels x 24 V x {1, 2, 3} A = 144, 288, 432 W at t = 0, 2, 4 s (trapezoids)
    assert metrics.energy_wh == pytest.approx((2 * (144 + 288) / 2 + 2 * (288 + 432) / 2) / 3600.0)
    assert metrics.energy_regenerated_wh == 0.0


def test_braking_power_is_counted_in_the_net_energy_and_on_its_own() -> None:
    buffer = io.BytesIO()
    with McapRecorder(buffer) as rec:
        # 6 wheels x 24 V x {2, -1, -1, 2} A: 288, -144, -144, 288 W at t = 0, 1, 2, 3 s.
        for i, current in enumerate([2.0, -1.0, -1.0, 2.0]):
            t_ns = to_ns(float(i))
            rec.publish(TRUTH_POSE, t_ns, _pose(t_ns, float(i), 0.0))
            rec.publish_bytes(WHEELS_STATUS, t_ns, json.dumps(_wheels(t_ns, current)).encode())
    metrics = compute_metrics(io.BytesIO(buffer.getvalue()))
    net_j = (288 - 144) / 2 + (-144 - 144) / 2 + (-144 + 288) / 2
    assert metrics.energy_wh == pytest.approx(net_j / 3600.0)
    assert metrics.energy_regenerated_wh == pytest.approx((144 / 2 + 144 + 144 / 2) / 3600.0)


def test_a_turns_braking_side_counts_as_regenerated_though_the_six_draw() -> None:
    buffer = io.BytesIO()
    with McapRecorder(buffer) as rec:
        for i in range(3):
            t_ns = to_ns(float(i))
            rec.publish(TRUTH_POSE, t_ns, _pose(t_ns, float(i), 0.0))
            status = _wheels(t_ns, 2.0)
            for wheel in status["wheels"][:3]:
                wheel["input_current_a"] = -0.5  # the inner side brakes: 3 x 12 W back, 3 x 48 W drawn
            rec.publish_bytes(WHEELS_STATUS, t_ns, json.dumps(status).encode())
    metrics = compute_metrics(io.BytesIO(buffer.getvalue()))
    assert metrics.energy_wh == pytest.approx(2.0 * 108.0 / 3600.0)
    assert metrics.energy_regenerated_wh == pytest.approx(2.0 * 36.0 / 3600.0)
