"""Success criteria: each failed one in words; the ground-truth goal distance can be required."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from hil.scenario import SuccessCriteria, load_scenario
from hil.success import judge
from logs.metrics import TrialMetrics
from logs.settings import ConfigError

DATA = Path(__file__).resolve().parents[1] / "data"

# A run the rover itself called arrived, 0.71 m from the true goal (as 12 of 18 campaign runs were).
ARRIVED_SHORT = TrialMetrics(
    trajectory_topic="truth/pose",
    duration_s=38.800000000000004,
    distance_m=12.0,
    path_tolerance_m=0.5,
    path_accuracy_pct=91.23456,
    route_length_m=12.5,
    route_accuracy_pct=90.0,
    encounter_margin_m=2.5,
    obstacles_encountered=1,
    obstacles_avoided=1,
    obstacle_avoidance_success_pct=100.0,
    collisions=0,
    rollovers=0,
    energy_wh=1.0,
    energy_wh_per_m=0.08,
    goal_reached=True,
    final_distance_to_goal_m=0.71,
    cross_track_error_rms_m=0.1,
    cross_track_error_max_m=0.3,
)


def test_the_default_criteria_pass_a_run_the_rover_called_arrived():
    assert judge(SuccessCriteria(), ARRIVED_SHORT) == []


def test_max_final_distance_judges_the_ground_truth_not_the_rovers_arrival():
    (failure,) = judge(SuccessCriteria(max_final_distance_m=0.5), ARRIVED_SHORT)
    assert failure == "final distance to goal (ground truth) 0.71 m > 0.5 m"
    assert judge(SuccessCriteria(max_final_distance_m=0.75), ARRIVED_SHORT) == []


def test_a_metric_the_recording_lacks_fails_the_criterion_that_needs_it():
    unknown = dataclasses.replace(ARRIVED_SHORT, final_distance_to_goal_m=None)
    assert judge(SuccessCriteria(max_final_distance_m=0.5), unknown) == [
        "final distance to goal (ground truth) unknown m > 0.5 m"
    ]


def test_every_failed_criterion_is_listed_with_rounded_figures():
    failed = dataclasses.replace(ARRIVED_SHORT, goal_reached=False, collisions=2, rollovers=1)
    criteria = SuccessCriteria(max_collisions=0, min_path_accuracy_pct=95.0, max_duration_s=5.0)
    assert judge(criteria, failed) == [
        "goal not reached (the rover never reported ARRIVED at the last goal)",
        "rollovers 1 > 0",
        "collisions 2 > 0",
        # "of driven": the campaign tables' first Path Accuracy column is the route's, another figure.
        "path accuracy (% of driven) 91.2 % < 95 %",
        "duration 38.8 s > 5 s",
    ]


def _scenario_with_success(tmp_path: Path, table: str) -> Path:
    path = tmp_path / "scenario.toml"
    path.write_text((DATA / "small_rocky.toml").read_text() + f"\n[success]\n{table}\n", encoding="utf-8")
    return path


def test_scenario_reads_max_final_distance(tmp_path):
    scenario = load_scenario(_scenario_with_success(tmp_path, "max_final_distance_m = 0.5"))
    assert scenario.success.max_final_distance_m == 0.5
    assert load_scenario(DATA / "small_rocky.toml").success.max_final_distance_m is None


def test_scenario_rejects_a_negative_max_final_distance(tmp_path):
    with pytest.raises(ConfigError, match=r"scenario\.toml.*max_final_distance_m"):
        load_scenario(_scenario_with_success(tmp_path, "max_final_distance_m = -1.0"))
