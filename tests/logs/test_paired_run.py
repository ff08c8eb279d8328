"""A real-time HIL run is two recordings (the rover's, the peer's truth): ``rover logs report`` reports it
as one run measured on the truth, with the same figures as the same trial recorded in one file. The pair
is made as ``tests.logs.realtime_pair`` says: split from one synthetic trial, with the peer's extra
truth before the rover started and after it stopped.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from hil.realtime_metrics import realtime_metrics
from logs.analysis import analyse
from logs.report import ReportError, write_report
from logs.topics import TRUTH_POSE
from rover_cli.main import main
from tests.logs.realtime_pair import PEER_EARLY_NS
from tests.logs.realtime_pair import write_pair as _write_pair


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


def _inside_a_chunk(path: Path) -> int:
    """The offset of a byte in the middle of the compressed records of the file's middle chunk (the file's
    middle byte may be a chunk's header, whose damage a reader need not notice)."""
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and summary.chunk_indexes
    chunk = summary.chunk_indexes[len(summary.chunk_indexes) // 2]
    records_end = chunk.chunk_start_offset + chunk.chunk_length
    return records_end - chunk.compressed_size // 2


@pytest.mark.parametrize("truth_kind", ["not MCAP", "missing", "damaged"])
def test_an_unreadable_truth_is_named_and_the_rover_run_kept(tmp_path: Path, truth_kind: str) -> None:
    """`rover logs report rover.mcap --truth T` with a T that cannot be read once dropped the rover's
    readable recording too ("skipped rover.mcap: T is not an MCAP file", exit 2: no report of the run)."""
    _, rover, good_truth = _write_pair(tmp_path / "runs")
    truth = tmp_path / "truth.mcap"
    if truth_kind == "not MCAP":
        truth.write_bytes(b"not a recording\n")
    elif truth_kind == "damaged":
        data = bytearray(good_truth.read_bytes())
        data[_inside_a_chunk(good_truth)] ^= 0xFF  # a flipped byte inside a chunk: it fails its CRC
        truth.write_bytes(bytes(data))
    out = tmp_path / "out"
    assert main(["logs", "report", str(rover), "--truth", str(truth), "--out", str(out), "--no-plots"]) == 1
    document = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert document["failed"] == {}
    (run,) = document["runs"]
    assert (run["path"], run["truth_path"], run["truth_merged"]) == (str(rover), str(truth), False)
    assert run["metrics"]["trajectory_topic"] == "estimator/pose"  # the rover's own estimate
    assert run["figures"]["can_frames"]
    assert any(f"{truth}: not merged: not readable" in p for p in run["metrics"]["problems"])


def test_an_empty_truth_is_named_and_the_rover_file_not_called_cut(tmp_path: Path) -> None:
    """An empty truth.mcap (the peer killed before it wrote a byte) was reported as "recording is cut
    short; metrics cover the part before the cut", of a rover recording that was whole."""
    _, rover, _ = _write_pair(tmp_path / "runs")
    truth = tmp_path / "truth.mcap"
    truth.write_bytes(b"")
    (run,) = write_report([rover], tmp_path / "out", plots=False, truth=truth).runs
    assert not run.metrics.truncated
    assert not any("cut short" in p for p in run.metrics.problems), run.metrics.problems
    assert any(f"{truth}: not merged: not readable ({truth} is empty" in p for p in run.metrics.problems)


def test_a_truth_that_ends_before_the_drive_says_so_and_gives_no_energy_per_metre(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The peer stopped before the rover did (docs/hil.md: a peer given 75 s for a 60 s run). The report
    said nothing, exit 0, and divided the energy of the whole drive by the distance of the truth's part
    of it: 0.060 Wh/m on a run of 0.025."""
    reference, rover, truth = _write_pair(tmp_path / "runs", truth_until_s=6.0)
    out = tmp_path / "out"
    assert main(["logs", "report", str(rover), "--truth", str(truth), "--out", str(out), "--no-plots"]) == 0
    assert "the truth ends" in " ".join(capsys.readouterr().out.split())
    (run,) = json.loads((out / "report.json").read_text(encoding="utf-8"))["runs"]
    whole = analyse(reference).metrics
    assert run["truth_merged"] and whole.distance_m is not None
    assert run["metrics"]["distance_m"] < 0.6 * whole.distance_m  # the truth's part
    assert run["metrics"]["energy_wh"] == pytest.approx(whole.energy_wh, rel=1e-6)  # the whole drive
    assert run["metrics"]["energy_wh_per_m"] is None
    assert any(f"{truth}: the truth ends" in p for p in run["metrics"]["problems"])
    assert realtime_metrics(rover, truth).energy_wh_per_m is None  # the Python API says the same

    _, rover, truth = _write_pair(tmp_path / "whole")
    (run_whole,) = write_report([rover], tmp_path / "out-whole", plots=False, truth=truth).runs
    assert run_whole.metrics.energy_wh_per_m is not None and not run_whole.metrics.problems


def test_a_truth_of_another_peer_run_is_not_merged_with_one_rover_recording(tmp_path: Path) -> None:
    """Two HIL runs at once (two peers, two rovers): `rover logs report R1.mcap --truth T2.mcap`, the other
    run's truth, was merged as this run's (exit 0, its figures measured on the other rover's drive): the
    peer run ids both files record were compared only when several pairs were given."""
    _, rover, _ = _write_pair(tmp_path / "one", peer_run="aaaa1111", seed=1)
    _, _, other_truth = _write_pair(tmp_path / "two", peer_run="bbbb2222", seed=2, wobble_m=0.6)
    for given in (["--truth", str(other_truth)], [str(other_truth)]):  # with --truth, and paired as given
        out = tmp_path / f"out{len(given)}"
        assert main(["logs", "report", str(rover), *given, "--out", str(out), "--no-plots"]) == 1
        (run,) = json.loads((out / "report.json").read_text(encoding="utf-8"))["runs"]
        assert (run["truth_path"], run["truth_merged"]) == (str(other_truth), False)
        assert run["metrics"]["trajectory_topic"] == "estimator/pose"
        assert any("bbbb2222" in p and "aaaa1111" in p for p in run["metrics"]["problems"])
