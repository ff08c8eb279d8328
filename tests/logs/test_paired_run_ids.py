"""The HIL peer run ids of a (rover, truth) pair are judged by one rule, for one pair (``read_paired``) and
for several (``misplaced_truths``): each file's run is its ``peer`` ``run`` or else its ``trial``
``hil_peer_run``, whichever file it is given as, a later metadata record of a name replacing an earlier
one. The two used to read them differently: a pair of files of two runs was refused among several pairs
and merged (or reported as merely not overlapping) when given alone."""

from __future__ import annotations

from pathlib import Path

import pytest

from logs.metrics import METRIC_TOPICS
from logs.paired_run import misplaced_truths, read_paired
from logs.reader import RecordedMessage, RecordedMetadata, read_entries
from logs.recorder import McapRecorder
from tests.logs.realtime_pair import write_pair

RUN_A, RUN_B = "aaaa1111", "bbbb2222"


def _renamed_run_later(rover: Path, out: Path, run: str) -> Path:
    """``rover`` copied with a second ``trial`` record after the first, naming ``run``: the later record is
    the one a reader of the outline takes."""
    with McapRecorder(out) as recorder:
        for entry in read_entries(rover):  # the rover side of a pair: metadata and messages only
            if isinstance(entry, RecordedMetadata):
                recorder.add_metadata(entry.name, entry.data)
            elif isinstance(entry, RecordedMessage):
                recorder.publish(entry.topic, entry.log_time_ns, entry.message)
        recorder.add_metadata("trial", {"mode": "rover-run", "hil_peer_run": run})
    return out


def _pair(kind: str, tmp_path: Path) -> tuple[Path, Path]:
    """(rover, truth) as given, of two runs: ``RUN_A``'s rover side, ``RUN_B``'s other file."""
    _, rover_a, truth_a = write_pair(tmp_path / "a", peer_run=RUN_A, seed=1)
    _, rover_b, truth_b = write_pair(tmp_path / "b", peer_run=RUN_B, seed=2, wobble_m=0.6)
    if kind == "another run's rover recording as the truth":
        return rover_a, rover_b
    if kind == "two truths of two runs":
        return truth_a, truth_b
    # A rover recording whose first trial record names no run, and a later one names RUN_A.
    _, unnamed, _ = write_pair(tmp_path / "c", seed=1)
    return _renamed_run_later(unnamed, tmp_path / "renamed.mcap", RUN_A), truth_b


@pytest.mark.parametrize(
    "kind",
    [
        "another run's rover recording as the truth",
        "two truths of two runs",
        "a later trial record names the run",
    ],
)
def test_files_of_two_peer_runs_are_refused_alone_as_among_several_pairs(kind: str, tmp_path: Path) -> None:
    rover, truth = _pair(kind, tmp_path)
    (among_pairs,) = misplaced_truths([(rover, truth)])
    assert RUN_A in among_pairs and RUN_B in among_pairs
    paired = read_paired(rover, truth, topics=METRIC_TOPICS)
    list(paired.entries)
    assert paired.refused
    assert any(f"recorded by HIL peer run {RUN_B}" in p and RUN_A in p for p in paired.problems)


def test_files_of_one_peer_run_are_merged_alone_and_pass_among_several_pairs(tmp_path: Path) -> None:
    _, rover, truth = write_pair(tmp_path / "a", peer_run=RUN_A)
    assert misplaced_truths([(rover, truth)]) == []
    paired = read_paired(rover, truth, topics=METRIC_TOPICS)
    list(paired.entries)
    assert not paired.refused and paired.truth_kept > 0 and paired.problems == []
