"""A report lists each run's safety/events (failsafes, modes, goals, what the rover learned) in time order,
up to a cap; the rest are counted and the report says where all of them are."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from logs import analysis
from logs.recorder import McapRecorder
from logs.report import write_report
from logs.synthetic import synthetic_metadata, write_synthetic_trial
from logs.topics import SAFETY_EVENTS, stamp

EVENTS = [
    (2.0, "info", "mode", "IDLE -> DRIVING: guidance has a path"),
    (23.04, "error", "failsafe.no_progress", "commanded 0.71 m/s for 10 s but moved 0.40 m | dug in"),
    (23.05, "warning", "learned.terrain", "friction_mu 0.32 (believed 0.40) <planning again>"),
]


def _trial_with_events(path: Path, events: list[tuple[float, str, str, str]]) -> Path:
    with McapRecorder(path) as recorder:
        recorder.add_metadata("scenario", synthetic_metadata(30.0))
        write_synthetic_trial(recorder, 30.0)
        for t_s, severity, kind, detail in events:
            t_ns = int(t_s * 1e9)
            message = {"timestamp": stamp(t_ns), "kind": kind, "severity": severity, "detail": detail}
            recorder.publish(SAFETY_EVENTS, t_ns, message)
    return path


def test_the_report_lists_the_events_in_time_order_in_every_format(tmp_path: Path) -> None:
    source = _trial_with_events(tmp_path / "run.mcap", EVENTS)
    result = write_report([source], tmp_path / "out", plots=False)
    markdown = result.markdown.read_text()
    rows = [line for line in markdown.splitlines() if line.startswith("| ") and "failsafe" in line]
    assert rows == [
        "| 23.04 | error | failsafe.no_progress | commanded 0.71 m/s for 10 s but moved 0.40 m \\| dug in |"
    ]
    assert (
        markdown.index("| mode |")
        < markdown.index("| failsafe.no_progress |")
        < markdown.index("| learned.terrain |")
    )
    assert "more not listed" not in markdown
    html = result.html.read_text()
    assert "<td>learned.terrain</td><td>friction_mu 0.32 (believed 0.40) &lt;planning again&gt;</td>" in html
    listed = json.loads(result.json.read_text())["runs"][0]
    assert [(e["t_s"], e["kind"]) for e in listed["events"]] == [(t, kind) for t, _, kind, _ in EVENTS]
    assert listed["events_unlisted"] == 0


def test_past_the_cap_the_rest_are_counted_and_a_late_failsafe_is_still_listed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(analysis, "EVENTS_LISTED", 2)
    chatter = [(1.0 + i, "info", "mode", f"change {i}") for i in range(5)]
    source = _trial_with_events(tmp_path / "run.mcap", [*chatter, EVENTS[1]])
    result = write_report([source], tmp_path / "out", plots=False)
    markdown = result.markdown.read_text()
    assert "| change 1 |" in markdown and "| change 2 |" not in markdown  # info: the first two
    assert "| failsafe.no_progress |" in markdown  # after all the chatter, listed all the same
    assert f"3 more not listed (`rover logs csv {source} --out DIR --topics safety/events`" in markdown
    listed = json.loads(result.json.read_text())["runs"][0]
    assert len(listed["events"]) == 3 and listed["events_unlisted"] == 3
    # The counts by severity are of every event, listed or not.
    assert listed["figures"]["safety_errors"] == 1


def test_odd_details_stay_in_their_cell_and_events_read_in_time_order(tmp_path: Path) -> None:
    events = [
        (9.0, "warning", "late", "a\\b | c\nsecond line <b>&"),
        (4.0, "info", "early", ""),  # recorded after, happened before (a CAN thread's event)
    ]
    source = _trial_with_events(tmp_path / "run.mcap", events)
    markdown = write_report([source], tmp_path / "out", plots=False).markdown.read_text()
    assert "| 9.00 | warning | late | a\\\\b \\| c<br>second line &lt;b&gt;&amp; |\n" in markdown
    assert markdown.index("| early |") < markdown.index("| late |")


def test_an_event_without_a_detail_is_counted_and_listed(tmp_path: Path) -> None:
    """Only its severity was needed to count it before the table: an event without one of the table's
    fields must not become unusable and drop out of the counts."""
    path = tmp_path / "run.mcap"
    with McapRecorder(path) as recorder:
        recorder.add_metadata("scenario", synthetic_metadata(30.0))
        write_synthetic_trial(recorder, 30.0)
        recorder.publish(
            SAFETY_EVENTS, 5_000_000_000, {"timestamp": stamp(5_000_000_000), "severity": "warning"}
        )
    listed = json.loads(write_report([path], tmp_path / "out", plots=False).json.read_text())["runs"][0]
    assert listed["figures"]["safety_warnings"] == 1 and listed["figures"]["unusable_messages"] == 0
    assert [(e["kind"], e["detail"]) for e in listed["events"]] == [("", "")]
