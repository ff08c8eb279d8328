"""Recordings made before the body could slide sideways: their ``truth/pose`` has no ``lateral_speed_mps``.
The schema does not require it, and metrics and reports read such a recording as before."""

from __future__ import annotations

from pathlib import Path

from logs.metrics import compute_metrics
from logs.recorder import McapRecorder
from logs.report import write_report
from logs.synthetic import synthetic_metadata, synthetic_trial
from logs.topics import TOPICS, TRUTH_POSE

DURATION_S = 10.0


def _write_old(path: Path) -> Path:
    """A synthetic trial whose truth/pose messages lack the sideways speed, as old recordings'."""
    with McapRecorder(path) as recorder:
        recorder.add_metadata("scenario", synthetic_metadata(DURATION_S))
        for topic, t, message in synthetic_trial(DURATION_S):
            if topic == TRUTH_POSE:
                message = {k: v for k, v in message.items() if k != "lateral_speed_mps"}
            recorder.publish(topic, t, message)
    return path


def test_the_schema_does_not_require_the_sideways_speed() -> None:
    schema = TOPICS[TRUTH_POSE].schema
    assert "lateral_speed_mps" in schema["properties"]
    assert "lateral_speed_mps" not in schema["required"]
    old = next(m for topic, _, m in synthetic_trial(1.0) if topic == TRUTH_POSE)
    old.pop("lateral_speed_mps")
    assert set(schema["required"]) <= set(old)  # an old message has every field the schema requires


def test_metrics_and_reports_read_a_truth_pose_without_it(tmp_path: Path) -> None:
    old = _write_old(tmp_path / "old.mcap")
    metrics = compute_metrics(old)
    assert metrics.distance_m is not None and metrics.distance_m > 1.0
    assert metrics.duration_s is not None and metrics.duration_s > 9.0
    text = write_report([old], tmp_path / "report", plots=False).markdown.read_text(encoding="utf-8")
    assert ", truth)" in text  # its figures come from the truth it has
