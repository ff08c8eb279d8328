"""A simulated trial against the same trial as a real run would record it (no ``truth/*`` topics): the
report must find them the same run, and measure the real one's distance without the estimate's jitter."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from hil.scenario import Scenario
from hil.trial import TrialResult, run_trial
from logs.analysis import analyse
from logs.compare import compare_runs
from logs.metrics import compute_metrics
from navigator.config import RoverConfig


def copy_without_truth(source: Path, target: Path) -> Path:
    """``source`` as a ``rover run`` recording looks: every message, metadata and attachment but the
    simulator's ``truth/*`` topics."""
    with source.open("rb") as inp, target.open("wb") as out:
        reader = make_reader(inp)
        writer = Writer(out)
        writer.start()
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if channel.topic.startswith("truth/"):
                continue
            if schema is not None and schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                schema_id = schemas.get(channel.schema_id, 0)
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schema_id, dict(channel.metadata)
                )
            writer.add_message(
                channels[channel.id], message.log_time, message.data, message.publish_time, message.sequence
            )
        for record in reader.iter_metadata():
            writer.add_metadata(record.name, dict(record.metadata))
        writer.finish()
    return target


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
