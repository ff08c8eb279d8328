"""A simulated trial against the same trial as a real run would record it (no ``truth/*`` topics): the
report must find them the same run, and measure the real one's distance without the estimate's jitter."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.scenario import Scenario
from hil.trial import TrialResult, run_trial
from logs.analysis import analyse
from logs.compare import compare_runs
from logs.metrics import compute_metrics
from navigator.config import RoverConfig
from tests.mcap_rewrite import rewrite


def copy_without_truth(source: Path, target: Path) -> Path:
    """``source`` as a ``rover run`` recording looks: every message and metadata record but the simulator's
    ``truth/*`` topics."""
    return rewrite(source, target, keep=lambda topic: not topic.startswith("truth/"))


@pytest.fixture(scope="module")
def real_copy(small_trial: TrialResult, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return copy_without_truth(small_trial.mcap_path, tmp_path_factory.mktemp("real") / "real.mcap")


def test_a_run_compared_with_its_own_real_copy_shows_no_gap(
    small_trial: TrialResult, real_copy: Path
) -> None:
    sim, real = analyse(small_trial.mcap_path), analyse(real_copy)
    assert real.metrics.trajectory_topic == "estimator/pose"
    comparison = compare_runs(sim, real)
    # the same run: what is left is the estimator's own error across the track (docs/metrics.md)
    assert comparison.gap_rms_m is not None and comparison.gap_rms_m < 0.2
    assert comparison.gap_max_m is not None and comparison.gap_max_m < 0.6
    assert not comparison.not_comparable


def test_the_real_copy_measures_the_distance_driven_without_the_jitter(
    small_trial: TrialResult, real_copy: Path
) -> None:
    truth, real = small_trial.metrics, compute_metrics(real_copy)
    assert truth.distance_m is not None and real.distance_m is not None
    assert real.distance_m == pytest.approx(truth.distance_m, rel=0.02)
    assert real.energy_wh_per_m == pytest.approx(truth.energy_wh_per_m, rel=0.02)


def test_two_seeds_real_copies_differ_about_as_much_as_their_truths(
    small_trial: TrialResult,
    real_copy: Path,
    small_scenario: Scenario,
    default_config: RoverConfig,
    tmp_path: Path,
) -> None:
    other = run_trial(small_scenario, default_config, tmp_path / "other", seed=small_scenario.seed + 1)
    other_real = copy_without_truth(other.mcap_path, tmp_path / "other-real.mcap")
    truths = compare_runs(analyse(small_trial.mcap_path), analyse(other.mcap_path))
    reals = compare_runs(analyse(real_copy), analyse(other_real))
    assert truths.gap_rms_m is not None and reals.gap_rms_m is not None
    # the estimates add their own error (~0.1 m across the track) to the runs' true difference
    assert reals.gap_rms_m == pytest.approx(truths.gap_rms_m, abs=0.1)
