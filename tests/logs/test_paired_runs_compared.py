"""Two real-time HIL runs, each two recordings (the rover's, the peer's truth), reported with ``--truth``
once per rover recording, paired in order: each run is measured on its own truth, and the two are compared
as two lockstep trials of the same drives are. Pairs that cannot be right are refused before anything is
written (exit 2), naming the files; a truth of no given run is said in its run's part (exit 1).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from logs.analysis import analyse
from logs.compare import compare_runs
from logs.reader import RecordedMessage, read_entries, read_outline
from logs.topics import TRUTH_POSE
from rover_cli.main import main
from tests.logs.damaged_recording import write_small_trial
from tests.logs.realtime_pair import BOOT_NS, write_pair

LATER_NS = 600_000_000_000  # the second run starts ten minutes after the first


def _two_runs(folder: Path) -> tuple[tuple[Path, Path, Path], tuple[Path, Path, Path]]:
    """(reference, rover, truth) of two runs that drive differently (wobble 0.3 m and 1.2 m)."""
    first = write_pair(folder / "a", wobble_m=0.3, seed=1)
    second = write_pair(folder / "b", boot_ns=BOOT_NS + LATER_NS, wobble_m=1.2, seed=2)
    return first, second


def _report(*arguments: Path | str) -> list[str]:
    return ["logs", "report", *map(str, arguments), "--no-plots"]


def test_two_pairs_are_each_measured_on_their_truth_and_compared(tmp_path: Path) -> None:
    (ref_a, rover_a, truth_a), (ref_b, rover_b, truth_b) = _two_runs(tmp_path / "runs")
    out = tmp_path / "out"
    code = main(_report(rover_a, rover_b, "--truth", truth_a, "--truth", truth_b, "--out", out))
    assert code == 0
    document = json.loads((out / "report.json").read_text(encoding="utf-8"))
    runs = document["runs"]
    assert [(r["path"], r["truth_path"]) for r in runs] == [
        (str(rover_a), str(truth_a)),
        (str(rover_b), str(truth_b)),
    ]
    for run, reference in zip(runs, (ref_a, ref_b), strict=True):
        expected = analyse(reference)
        assert run["truth_merged"] and run["metrics"]["trajectory_topic"] == TRUTH_POSE
        # every metric as the same drive recorded in one file (as report.json writes them)
        assert run["metrics"] == json.loads(json.dumps(expected.metrics.to_dict(), default=str))
    (comparison,) = document["comparisons"]
    assert (comparison["a"], comparison["b"]) == (str(rover_a), str(rover_b))
    lockstep = compare_runs(analyse(ref_a), analyse(ref_b))  # the same two drives, one file each
    assert comparison["comparable"] and comparison["points"] == len(lockstep.s_m) > 10
    gaps = comparison["points_by_distance"]["position_gap_m"]
    assert gaps == pytest.approx(lockstep.position_gap_m)  # point by point, on the two truths
    assert comparison["position_gap_rms_m"] == pytest.approx(lockstep.gap_rms_m)
    assert comparison["position_gap_rms_m"] > 0.3  # the wobbles differ by 0.9 m
    accuracy = comparison["metrics"]["path_accuracy_pct"]
    assert accuracy["difference"] == pytest.approx(lockstep.metrics["path_accuracy_pct"]["difference"])


def test_a_count_that_differs_is_refused_naming_the_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (_, rover_a, truth_a), (_, rover_b, truth_b) = _two_runs(tmp_path / "runs")
    out = tmp_path / "out"
    assert main(_report(rover_a, rover_b, "--truth", truth_a, "--out", out)) == 2
    printed = " ".join(capsys.readouterr().out.split())
    assert f"--truth {truth_a}: each --truth pairs with one rover recording" in printed
    assert f"1 --truth and 2 recordings given ({rover_a}, {rover_b})" in printed
    assert main(_report(rover_a, "--truth", truth_a, "--truth", truth_b, "--out", out)) == 2
    assert "2 --truth and 1 recordings given" in " ".join(capsys.readouterr().out.split())
    assert not out.exists()  # nothing written


def test_swapped_truths_are_refused_naming_whose_each_is(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (_, rover_a, truth_a), (_, rover_b, truth_b) = _two_runs(tmp_path / "runs")
    out = tmp_path / "out"
    assert main(_report(rover_a, rover_b, "--truth", truth_b, "--truth", truth_a, "--out", out)) == 2
    printed = " ".join(capsys.readouterr().out.split())
    assert (
        f"--truth {truth_b} (truth 1) pairs with rover recording 1 ({rover_a}) but was recorded while "
        f"rover recording 2 ({rover_b}) ran" in printed
    )
    assert f"--truth {truth_a} (truth 2)" in printed and "give them in that order" in printed
    assert not out.exists()


def test_runs_recorded_at_the_same_time_are_paired_by_their_peer_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Two rovers against two peers on one machine, at the same time: the spans overlap and cannot tell
    # the truths apart (swapped, they used to be reported as each other's). The peer run ids can.
    rover_a, truth_a = write_pair(tmp_path / "a", wobble_m=0.3, seed=1, peer_run="aaaa1111")[1:]
    rover_b, truth_b = write_pair(tmp_path / "b", wobble_m=1.2, seed=2, peer_run="bbbb2222")[1:]
    out = tmp_path / "out"
    assert main(_report(rover_a, rover_b, "--truth", truth_b, "--truth", truth_a, "--out", out)) == 2
    printed = " ".join(capsys.readouterr().out.split())
    assert (
        f"--truth {truth_b} (truth 1) pairs with rover recording 1 ({rover_a}) but was recorded by HIL peer "
        f"run bbbb2222, and {rover_a} ran against peer run aaaa1111; it is the truth of rover recording 2"
        in printed
    )
    assert not out.exists()
    assert main(_report(rover_a, rover_b, "--truth", truth_a, "--truth", truth_b, "--out", out)) == 0


def test_a_directory_with_truth_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (_, rover_a, truth_a), _ = _two_runs(tmp_path / "runs")
    folder = rover_a.parent
    assert main(_report(folder, "--truth", truth_a, "--out", tmp_path / "out")) == 2
    printed = " ".join(capsys.readouterr().out.split())
    assert f"{folder} is a directory" in printed and "give each rover recording as a file" in printed


def test_a_truth_of_no_given_run_is_named_with_its_pair_and_the_other_run_kept(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (_, rover_a, truth_a), (_, rover_b, _) = _two_runs(tmp_path / "runs")
    _, _, elsewhere = write_pair(tmp_path / "runs" / "c", boot_ns=BOOT_NS + 2 * LATER_NS)
    out = tmp_path / "out"
    assert main(_report(rover_a, rover_b, "--truth", truth_a, "--truth", elsewhere, "--out", out)) == 1
    printed = " ".join(capsys.readouterr().out.split())
    assert f"real-time run: {rover_a} + truth {truth_a}" in printed
    assert (
        f"truth not merged with {rover_b}: {elsewhere}: no truth message inside the rover's drive" in printed
    )
    runs = json.loads((out / "report.json").read_text(encoding="utf-8"))["runs"]
    assert [run["truth_merged"] for run in runs] == [True, False]
    assert runs[1]["metrics"]["trajectory_topic"] == "estimator/pose"


def test_a_lockstep_trial_among_the_pairs_is_its_own_file_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (_, rover_a, truth_a), (_, _, truth_b) = _two_runs(tmp_path / "runs")
    trial = write_small_trial(tmp_path / "trial.mcap", trial_mode="sim-lockstep")  # its own truth/*
    out = tmp_path / "out"
    assert main(_report(rover_a, trial, "--truth", truth_a, "--truth", truth_b, "--out", out)) == 1
    printed = " ".join(capsys.readouterr().out.split())
    assert f"truth not merged with {trial}: {truth_b}: not merged: {trial} is a lockstep trial" in printed
    runs = json.loads((out / "report.json").read_text(encoding="utf-8"))["runs"]
    assert [run["truth_merged"] for run in runs] == [True, False]
    assert runs[1]["metrics"] == json.loads(json.dumps(analyse(trial).metrics.to_dict(), default=str)) | {
        "problems": runs[1]["metrics"]["problems"]
    }  # the trial on its own truth, as without --truth


def test_the_outline_spans_the_recorded_log_times(tmp_path: Path) -> None:
    (_, rover, truth), _ = _two_runs(tmp_path / "runs")
    for path in (rover, truth):
        times = [e.log_time_ns for e in read_entries(path) if isinstance(e, RecordedMessage)]
        outline = read_outline(path)
        assert outline.span_ns == (min(times), max(times))
        assert outline.metadata["trial"]["mode"] in ("rover-run", "sim-realtime-peer")
