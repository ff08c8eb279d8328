"""``--truth`` pairs a ``rover run`` recording with its peer's truth by log time. Two lockstep trials both
count their simulated clock from 0, so their log times overlap whichever runs they are: pairing one
trial with another's truth must not merge them (it once reported a run with another seed's track: path
accuracy 7 %, an estimator error of 4.5 m, exit 0), but report the rover's file on its own and say why.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from logs.analysis import analyse
from logs.recorder import McapRecorder
from logs.report import write_report
from logs.synthetic import synthetic_metadata, synthetic_trial
from logs.topics import TRUTH_POSE
from rover_cli.main import main

DURATION_S = 10.0


def _lockstep_trial(path: Path, *, seed: int, wobble_m: float, with_truth: bool = True) -> Path:
    """A lockstep trial's recording as ``hil.trial`` writes it: simulated clock from 0, mode recorded."""
    with McapRecorder(path) as recorder:
        recorder.add_metadata("scenario", synthetic_metadata(DURATION_S) | {"seed": str(seed)})
        recorder.add_metadata("trial", {"mode": "sim-lockstep", "config": "<built-in defaults>"})
        for topic, t, message in synthetic_trial(DURATION_S, wobble_m=wobble_m, seed=seed):
            if with_truth or not topic.startswith("truth/"):
                recorder.publish(topic, t, message)
    return path


def test_a_lockstep_trial_is_not_paired_with_another_trials_truth(tmp_path: Path) -> None:
    own = _lockstep_trial(tmp_path / "seed1.mcap", seed=1, wobble_m=0.1)
    other = _lockstep_trial(tmp_path / "seed2.mcap", seed=2, wobble_m=1.5)
    (run,) = write_report([own], tmp_path / "out", plots=False, truth=other).runs
    alone = analyse(own)
    assert run.metrics.trajectory_topic == TRUTH_POSE  # its own truth, not the other trial's
    assert run.metrics.path_accuracy_pct == alone.metrics.path_accuracy_pct
    assert run.metrics.distance_m == alone.metrics.distance_m
    assert run.figures["estimator_position_error_rms_m"] == alone.figures["estimator_position_error_rms_m"]
    (problem,) = [p for p in run.metrics.problems if p not in alone.metrics.problems]
    assert str(other) in problem and "lockstep" in problem
    assert run.sources == [("everything (the truth file was not merged)", f"rover: {own}")]


def test_a_lockstep_copy_without_truth_is_not_paired_with_a_lockstep_truth(tmp_path: Path) -> None:
    """The same as a "real run" made by stripping a trial's truth: it stays estimate-only."""
    stripped = _lockstep_trial(tmp_path / "real.mcap", seed=1, wobble_m=0.1, with_truth=False)
    other = _lockstep_trial(tmp_path / "sim.mcap", seed=2, wobble_m=1.5)
    (run,) = write_report([stripped], tmp_path / "out", plots=False, truth=other).runs
    assert run.metrics.trajectory_topic == "estimator/pose"
    assert run.figures["estimator_position_error_rms_m"] is None
    assert any(str(other) in p and "lockstep" in p for p in run.metrics.problems)


def test_the_command_says_the_truth_was_not_merged_and_exits_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    own = _lockstep_trial(tmp_path / "seed1.mcap", seed=1, wobble_m=0.1)
    other = _lockstep_trial(tmp_path / "seed2.mcap", seed=2, wobble_m=1.5)
    out = tmp_path / "out"
    code = main(["logs", "report", str(own), "--truth", str(other), "--out", str(out), "--no-plots"])
    assert code == 1  # a report written without one of its inputs, the truth
    printed = " ".join(capsys.readouterr().out.split())
    assert "truth not merged" in printed and "real-time run" not in printed
    assert "not merged (the problem below says why)" in (out / "report.md").read_text(encoding="utf-8")
