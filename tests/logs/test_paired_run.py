"""A real-time HIL run is two recordings (the rover's, the peer's truth): ``rover logs report`` reports it
as one run measured on the truth, with the same figures as the same trial recorded in one file.

The pair is made by splitting one synthetic trial the way the two processes record it: the rover's file
without ``truth/*`` and without the scenario, the peer's file with only ``truth/*`` and the scenario,
both on a monotonic clock that is far from zero. The peer also records before the rover starts and after
it stops (standing, then pushed aside), which the merge must leave out.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from hil.realtime_metrics import realtime_metrics
from logs.analysis import analyse
from logs.paired_run import TRUTH_TOPICS
from logs.recorder import McapRecorder
from logs.report import ReportError, write_report
from logs.sink import Message
from logs.synthetic import synthetic_metadata, synthetic_trial
from logs.topics import TRUTH_POSE, stamp
from rover_cli.main import main

DURATION_S = 12.0
BOOT_NS = 5_072_000_000_000  # the monotonic clock's reading when the rover started: ~1.4 h after boot
PEER_EARLY_NS = 3_000_000_000  # the peer starts this long before the rover's first control tick
PUSHED_M = 1.0  # after the rover stopped, its simulated body is moved aside: not part of the drive


def _moved(message: Message, t_ns: int, x: float, y: float) -> Message:
    """A copy of a ``truth/pose`` message at another time and place, standing still."""
    moved = copy.deepcopy(message)
    moved["timestamp"] = stamp(t_ns)
    moved["pose"]["position"].update(x=x, y=y)
    moved["speed_mps"] = 0.0
    return moved


def _write_pair(folder: Path, *, clock_offset_ns: int = BOOT_NS) -> tuple[Path, Path, Path]:
    """(one-file reference, rover.mcap, truth.mcap) of the same synthetic trial."""
    folder.mkdir(parents=True, exist_ok=True)
    records = list(synthetic_trial(DURATION_S))
    scenario = synthetic_metadata(DURATION_S) | {"name": "synthetic-rocky", "seed": "3"}
    reference, rover, truth = folder / "lockstep.mcap", folder / "rover.mcap", folder / "truth.mcap"
    with McapRecorder(reference) as recorder:
        recorder.add_metadata("scenario", scenario)
        for topic, t, message in records:
            recorder.publish(topic, BOOT_NS + t, message)
    with McapRecorder(rover) as recorder:
        recorder.add_metadata("trial", {"mode": "rover-run", "config": "peer/rover-hil.toml"})
        for topic, t, message in records:
            if topic not in TRUTH_TOPICS:
                recorder.publish(topic, BOOT_NS + t, message)
    poses = [(t, m) for topic, t, m in records if topic == TRUTH_POSE]
    first, last = poses[0][1], poses[-1][1]
    start, end = first["pose"]["position"], last["pose"]["position"]
    with McapRecorder(truth) as recorder:
        recorder.add_metadata("scenario", scenario)
        recorder.add_metadata("trial", {"mode": "sim-realtime-peer", "config": "<built-in defaults>"})
        recorder.add_metadata("peer", {"mode": "sim-realtime-peer"})
        for k in range(30):  # the peer waits for the rover, standing at the start
            t = clock_offset_ns - PEER_EARLY_NS + k * 100_000_000
            recorder.publish(TRUTH_POSE, t, _moved(first, t, start["x"], start["y"]))
        for topic, t, message in records:
            if topic in TRUTH_TOPICS:
                recorder.publish(topic, clock_offset_ns + t, message)
        end_ns = clock_offset_ns + records[-1][1]
        for k in range(1, 11):  # after the rover stopped: pushed aside, 1 m over a second
            t = end_ns + k * 100_000_000
            recorder.publish(TRUTH_POSE, t, _moved(last, t, end["x"], end["y"] + PUSHED_M * k / 10))
    return reference, rover, truth


def test_the_pair_reports_as_one_run_with_the_one_file_figures(tmp_path: Path) -> None:
    reference, rover, truth = _write_pair(tmp_path / "runs")
    result = write_report([rover], tmp_path / "out", plots=False, truth=truth)
    (run,) = result.runs
    expected = analyse(reference)
    assert run.metrics.trajectory_topic == TRUTH_POSE
    assert run.metrics == expected.metrics  # duration, distance, accuracy: the peer's extra truth left out
    for figure in ("estimator_position_error_rms_m", "estimator_position_error_max_m"):
        assert run.figures[figure] == pytest.approx(expected.figures[figure])
        assert run.figures[figure] is not None
    assert not run.missing
    assert realtime_metrics(rover, truth) == run.metrics  # the Python API and the report agree

    document = json.loads(result.json.read_text(encoding="utf-8"))
    (reported,) = document["runs"]
    assert reported["truth_path"] == str(truth)
    assert reported["metadata"]["trial"]["mode"] == "rover-run"  # the rover's, not the peer's
    assert reported["metadata"]["truth:trial"]["mode"] == "sim-realtime-peer"
    text = result.markdown.read_text(encoding="utf-8")
    assert "Partial report" not in text
    sources = dict(run.sources)
    assert (
        str(truth) in sources["collisions and rollovers (truth/contacts), stability margin (truth/stability)"]
    )
    assert sources["estimator error"].startswith(f"rover: {rover}")
    assert f"| estimator error | rover: {rover}" in text


def test_the_two_files_given_alone_are_paired(tmp_path: Path) -> None:
    _, rover, truth = _write_pair(tmp_path / "runs")
    out = tmp_path / "out"
    assert main(["logs", "report", str(rover), str(truth), "--out", str(out), "--no-plots"]) == 0
    (run,) = json.loads((out / "report.json").read_text(encoding="utf-8"))["runs"]
    assert (run["path"], run["truth_path"]) == (str(rover), str(truth))
    assert run["metrics"]["trajectory_topic"] == TRUTH_POSE and run["missing"] == []


def test_a_truth_from_another_clock_is_named_and_the_rover_run_kept(tmp_path: Path) -> None:
    _, rover, truth = _write_pair(tmp_path / "runs", clock_offset_ns=PEER_EARLY_NS)  # a lockstep-like clock
    (run,) = write_report([rover], tmp_path / "out", plots=False, truth=truth).runs
    assert run.metrics.trajectory_topic == "estimator/pose"
    assert any("no truth message inside the rover's drive" in p for p in run.metrics.problems)
    assert run.figures["estimator_position_error_rms_m"] is None
    assert run.figures["can_frames"]  # the rover's own figures are all there


def test_truth_with_several_recordings_is_refused(tmp_path: Path) -> None:
    reference, rover, truth = _write_pair(tmp_path / "runs")
    with pytest.raises(ReportError, match="pairs with one rover recording"):
        write_report([reference, rover], tmp_path / "out", truth=truth)
    out = str(tmp_path / "out")
    assert main(["logs", "report", str(reference), str(rover), "--truth", str(truth), "--out", out]) == 2
