"""doctor, recover and report on synthetic recordings: healthy, cut, damaged, foreign and partial input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from logs.analysis import analyse
from logs.doctor import diagnose
from logs.errors import LogReadError, RecordingError
from logs.reader import ReadStats, read_messages
from logs.recorder import McapRecorder
from logs.recover import recover
from logs.report import ReportError, write_report
from logs.synthetic import synthetic_metadata, synthetic_trial
from logs.topics import (
    CAN_FRAMES,
    ESTIMATOR_POSE,
    NAVIGATOR_PATH,
    TRUTH_POSE,
    TRUTH_STABILITY,
    WHEELS_STATUS,
)

DURATION_S = 20.0  # one whole wobble period, so RMS values have closed forms


def _write(
    path: Path,
    *,
    wobble_m: float = 0.3,
    skip: frozenset[str] = frozenset(),
    terrain: str = "rocky",
    name: str | None = None,
) -> int:
    count = 0
    scenario = synthetic_metadata(DURATION_S, terrain)
    if name is not None:
        scenario["name"] = name
    with McapRecorder(path) as recorder:
        recorder.add_metadata("scenario", scenario)
        recorder.add_attachment("scenario.toml", "application/toml", b"name = 'synthetic'\n", 0)
        for topic, t, message in synthetic_trial(DURATION_S, wobble_m=wobble_m, terrain=terrain):
            if topic not in skip:
                recorder.publish(topic, t, message)
                count += 1
    return count


@pytest.fixture(scope="module")
def trial(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int]:
    path = tmp_path_factory.mktemp("synthetic") / "a.mcap"
    return path, _write(path)


def test_doctor_on_a_healthy_file(trial: tuple[Path, int]) -> None:
    path, count = trial
    findings = diagnose(path)
    assert findings.healthy, findings.problems
    assert findings.complete and findings.summary_present and findings.footer_present
    assert findings.messages == count
    # one chunk per second of log time (the crash budget), give or take the last partial one
    assert DURATION_S - 1 <= findings.chunks <= DURATION_S + 1
    assert findings.topics[CAN_FRAMES].messages == 14 * 50 * DURATION_S
    assert findings.metadata == ["scenario"] and findings.attachments == ["scenario.toml"]


@pytest.mark.parametrize("fraction", [0.1, 0.5, 0.93])
def test_recover_keeps_every_complete_chunk(trial: tuple[Path, int], tmp_path: Path, fraction: float) -> None:
    data = trial[0].read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * fraction)])
    before = diagnose(cut)
    assert not before.healthy and before.cut_at is not None
    result = recover(cut, tmp_path / "fixed.mcap")
    assert result.chunks_kept == before.chunks and result.messages == before.messages
    after = diagnose(tmp_path / "fixed.mcap")
    assert after.healthy and after.messages == before.messages
    # the messages kept are exactly the first ones of the original, unchanged
    original = [(m.topic, m.log_time_ns, m.message) for m in read_messages(trial[0])]
    kept = [(m.topic, m.log_time_ns, m.message) for m in read_messages(tmp_path / "fixed.mcap")]
    assert kept == original[: len(kept)]


def test_recover_skips_a_damaged_chunk_and_goes_on(trial: tuple[Path, int], tmp_path: Path) -> None:
    data = bytearray(trial[0].read_bytes())
    middle = len(data) // 2
    data[middle : middle + 64] = bytes(64)  # zero a stretch inside a compressed chunk
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    findings = diagnose(damaged)
    assert findings.chunks_damaged == 1 and any("damaged" in p for p in findings.problems)
    result = recover(damaged, tmp_path / "fixed.mcap")
    assert result.chunks_dropped == 1 and result.chunks_kept == findings.chunks - 1
    assert diagnose(tmp_path / "fixed.mcap").healthy


def test_recover_refuses_to_overwrite_its_input(trial: tuple[Path, int]) -> None:
    with pytest.raises(RecordingError, match="other than"):
        recover(trial[0], trial[0])


def test_foreign_files_give_a_clear_error(tmp_path: Path) -> None:
    text = tmp_path / "notes.mcap"
    text.write_text("hello, not a recording\n")
    with pytest.raises(LogReadError, match="not an MCAP file"):
        diagnose(text)
    with pytest.raises(LogReadError, match="not an MCAP file"):
        analyse(text)
    with pytest.raises(LogReadError, match="cannot open"):
        diagnose(tmp_path / "absent.mcap")


def test_report_single_run_has_metrics_plots_and_json(trial: tuple[Path, int], tmp_path: Path) -> None:
    result = write_report([trial[0]], tmp_path / "out")
    page = result.html.read_text(encoding="utf-8")
    assert page.count("<svg") == 4 and "<script" not in page and "http" not in page.split("<svg")[0]
    document = json.loads(result.json.read_text(encoding="utf-8"))
    run = document["runs"][0]
    # the synthetic run wobbles sin-wise with amplitude 0.3 m on a straight path: RMS = 0.3 / sqrt(2)
    assert run["metrics"]["cross_track_error_rms_m"] == pytest.approx(0.3 / 2**0.5, rel=1e-2)
    assert run["metrics"]["path_accuracy_pct"] == pytest.approx(100.0)
    assert run["figures"]["control_period_mean_ms"] == pytest.approx(20.0)
    # 14 extended 8-byte frames per 20 ms = 700 frames/s of 67 + 64 bits at 500 kbit/s
    assert run["figures"]["can_bus_load_mean_pct"] == pytest.approx(100 * 700 * 131 / 500_000, rel=1e-2)
    assert run["figures"]["estimator_position_error_rms_m"] == pytest.approx(0.1 * 2**0.5, rel=0.1)
    assert run["terrain_class"] == "rocky" and not run["missing"]
    assert "path accuracy (% of driven, truth)" in result.markdown.read_text(encoding="utf-8")


def test_report_with_missing_topics_is_partial_and_says_so(tmp_path: Path) -> None:
    partial = tmp_path / "partial.mcap"
    _write(partial, skip=frozenset({NAVIGATOR_PATH, WHEELS_STATUS, CAN_FRAMES, ESTIMATOR_POSE}))
    died = tmp_path / "died.mcap"
    died.write_bytes(b"")  # a recorder killed before its first byte: listed, the report goes on
    result = write_report([partial, died], tmp_path / "out", plots=False)
    assert str(died) in result.failed
    run = result.runs[0]
    assert {NAVIGATOR_PATH, WHEELS_STATUS, CAN_FRAMES, ESTIMATOR_POSE} <= set(run.missing)
    assert run.metrics.path_accuracy_pct is None and run.metrics.energy_wh is None
    assert run.metrics.cross_track_error_rms_m is not None  # what is there is still reported
    assert "Partial report, missing" in result.markdown.read_text(encoding="utf-8")


def test_a_run_without_truth_labels_its_figures_estimate(trial: tuple[Path, int], tmp_path: Path) -> None:
    real = tmp_path / "real.mcap"  # what `rover run` records: no truth/* topics
    _write(real, skip=frozenset({TRUTH_POSE, TRUTH_STABILITY}))
    result = write_report([real, trial[0]], tmp_path / "out", plots=False)
    assert [run.metrics.trajectory_topic for run in result.runs] == [ESTIMATOR_POSE, TRUTH_POSE]
    runs_part = result.markdown.read_text(encoding="utf-8").split("## Comparison")[0]
    real_part, sim_part = runs_part.split("## ")[1:]
    assert "trajectory: estimator/pose (estimate)" in real_part
    assert "| distance to goal at end (m, estimate) |" in real_part
    # Only the estimator's error is "vs truth" (n/a without it); no figure claims to be truth.
    truth_rows = [row for row in real_part.splitlines() if row.startswith("|") and "truth" in row]
    assert truth_rows and all("vs truth) | n/a |" in row for row in truth_rows), truth_rows
    assert "trajectory: truth/pose (truth)" in sim_part
    assert "| distance to goal at end (m, truth) |" in sim_part
    assert "distance to goal at end (m, estimate)" in result.html.read_text(encoding="utf-8")
    # The comparison plot's legend says it too.
    plotted = write_report([real, trial[0]], tmp_path / "plotted", plots=True).html.read_text(
        encoding="utf-8"
    )
    assert "A (estimate)" in plotted and "B (truth)" in plotted


def test_report_on_a_cut_file_covers_the_part_before_the_cut(trial: tuple[Path, int], tmp_path: Path) -> None:
    data = trial[0].read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    result = write_report([cut], tmp_path / "out", plots=False)
    metrics = result.runs[0].metrics
    assert metrics.truncated and 2.0 < (metrics.duration_s or 0.0) < DURATION_S


def test_two_runs_are_compared_by_distance(trial: tuple[Path, int], tmp_path: Path) -> None:
    other = tmp_path / "b.mcap"
    _write(other, wobble_m=0.5, terrain="sandy", name="synthetic-rocky")  # the same scenario, other ground
    result = write_report([trial[0], other], tmp_path / "out", plots=False)
    comparison = result.comparisons[0]
    # same speed, same line: the gap is the wobble difference, at most 0.2 m at the crests, where the two
    # tracks run parallel (the along-track window cannot find a nearer point there)
    assert not comparison.not_comparable
    assert comparison.gap_max_m == pytest.approx(0.2, abs=0.02)
    rms = comparison.metrics["cross_track_error_rms_m"]
    assert rms["difference"] == pytest.approx(0.2 / 2**0.5, rel=1e-2)
    keys = {d["key"] for d in comparison.metadata_differences}
    assert "scenario.terrain_class" in keys


def test_campaign_directory_gives_per_terrain_table(trial: tuple[Path, int], tmp_path: Path) -> None:
    campaign = tmp_path / "campaign"
    for index, terrain in enumerate(("rocky", "sandy", "sandy")):
        _write(campaign / f"run{index}" / "trial.mcap", wobble_m=0.2 + 0.5 * index, terrain=terrain)
    result = write_report([campaign], tmp_path / "out", plots=False)
    table = {row["terrain"]: row for row in result.terrain_table}
    assert table["rocky"]["runs"] == 1 and table["sandy"]["runs"] == 2
    assert table["rocky"]["path_accuracy_pct"] == pytest.approx(100.0)
    assert table["sandy"]["path_accuracy_pct"] < 100.0  # 0.7 and 1.2 m wobbles leave the 0.5 m tolerance
    assert "Per terrain" in result.markdown.read_text(encoding="utf-8")


def test_report_without_inputs_is_an_error(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(ReportError, match="no recordings"):
        write_report([tmp_path / "empty"], tmp_path / "out")


def test_raw_topics_are_left_undecoded(trial: tuple[Path, int]) -> None:
    from logs.reader import RecordedRaw, read_entries

    stats = ReadStats()
    raw = [e for e in read_entries(trial[0], topics=(), raw_topics=(CAN_FRAMES,), stats=stats)]
    frames = [e for e in raw if isinstance(e, RecordedRaw)]
    assert len(frames) == 14 * 50 * DURATION_S and json.loads(frames[0].data)["dlc"] == 8
