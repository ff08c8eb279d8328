"""`rover logs learned`: what recordings learned of the ground, as rover-config tables the config loader
takes (the next run's beliefs)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from logs.learned_terrain import learned_tables, read_learned
from logs.recorder import McapRecorder
from logs.settings import parse_toml
from logs.topics import NAVIGATOR_LEARNED, NAVIGATOR_STATE, stamp
from navigator.config import rover_config_from_table
from navigator.terrain_class_settings import override_refusal
from navigator.terrain_classes import TERRAIN_CLASSES
from rover_cli.main import main

SANDY = next(c for c in TERRAIN_CLASSES.values() if c.name == "sandy")
MUDDY = next(c for c in TERRAIN_CLASSES.values() if c.name == "muddy")


def _learned(t_s: float, class_name: str, class_id: int, value: Any) -> dict[str, Any]:
    return {
        "timestamp": stamp(int(t_s * 1e9)),
        "class_name": class_name,
        "class_id": class_id,
        "field": "friction_mu",
        "value": value,
        "believed": 0.4,
        "slope_rad": 0.164,
        "plans_up_to_rad": 0.147,
        "x": 15.1,
        "y": 3.1,
    }


def _recording(path: Path, learnings: list[dict[str, Any]], *, seconds: int = 30) -> Path:
    """A recording of ``seconds`` of navigator/state at 1 Hz with ``learnings`` among them, one chunk a
    second (so a cut keeps the seconds before it)."""
    by_second = {int(m["timestamp"]["sec"]): m for m in learnings}
    with McapRecorder(path, chunk_duration_ns=1_000_000_000) as recorder:
        for second in range(seconds):
            t_ns = second * 1_000_000_000
            recorder.publish(NAVIGATOR_STATE, t_ns, {"timestamp": stamp(t_ns), "mode": "DRIVING"})
            if second in by_second:
                recorder.publish(NAVIGATOR_LEARNED, t_ns + 1, by_second[second])
    return path


def _beliefs(tables: str) -> dict[str, float]:
    """The friction_mu the rover config built from ``tables`` believes, per class whose value moved."""
    config = rover_config_from_table(parse_toml(tables, "<learned>"))
    return {
        spec.name: spec.friction_mu
        for class_id, spec in config.classes.items()
        if spec.friction_mu != TERRAIN_CLASSES[class_id].friction_mu
    }


def test_the_tables_are_a_rover_config_that_believes_the_most_cautious_learning(tmp_path: Path) -> None:
    first = _recording(
        tmp_path / "a.mcap",
        [_learned(5, "sandy", SANDY.id, 0.32), _learned(12, "muddy", MUDDY.id, 0.21)],
    )
    second = _recording(tmp_path / "b.mcap", [_learned(8, "sandy", SANDY.id, 0.30)])
    read = read_learned([first, second])
    assert [(x.class_name, x.value) for x in read.learnings] == [
        ("sandy", 0.32),
        ("muddy", 0.21),
        ("sandy", 0.30),
    ]
    tables = learned_tables(read)
    assert _beliefs(tables) == {"sandy": 0.30, "muddy": 0.21}  # the lowest sandy of the two runs
    # Each learning named above its value: where, when, and what it was before.
    learned = "learned on a 9.4 deg slope; friction_mu 0.4 -> 0.32"
    assert f"# {first} at 5.00 s, at (15.1, 3.1): {learned}" in tables
    assert f"# {second} at 8.00 s" in tables
    assert not read.refused and not read.stops


def test_nothing_learned_is_a_comment_that_changes_no_belief(tmp_path: Path) -> None:
    quiet = _recording(tmp_path / "quiet.mcap", [])
    tables = learned_tables(read_learned([quiet]))
    assert tables.startswith("# Nothing learned") and _beliefs(tables) == {}
    assert main(["logs", "learned", str(quiet), "--out", str(tmp_path / "t.toml")]) == 0
    assert (tmp_path / "t.toml").read_text() == tables


@pytest.mark.parametrize(
    ("bad", "named"),
    [
        ({"value": "0.3"}, "value '0.3' is not a finite number"),
        ({"value": None}, "value None is not a finite number"),  # a NaN as JSON writes it
        ({"class_name": "sandy]\n[planner"}, "is not a plain name"),  # would write another table
        ({"field": None}, "field None is not a plain name"),
    ],
    ids=["text", "nan", "not-a-key", "no-field"],
)
def test_a_bad_message_is_refused_by_name_and_the_rest_are_taken(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], bad: dict[str, Any], named: str
) -> None:
    source = _recording(
        tmp_path / "r.mcap",
        [{**_learned(3, "sandy", SANDY.id, 0.2), **bad}, _learned(9, "sandy", SANDY.id, 0.33)],
    )
    read = read_learned([source])
    assert len(read.refused) == 1 and named in read.refused[0] and f"{source} at 3.000 s" in read.refused[0]
    assert _beliefs(learned_tables(read)) == {"sandy": 0.33}
    out = tmp_path / "t.toml"
    assert main(["logs", "learned", str(source), "--out", str(out)]) == 1  # written, but not from all
    assert named in capsys.readouterr().err
    assert _beliefs(out.read_text()) == {"sandy": 0.33}


def test_a_cut_recording_gives_what_it_learned_before_the_cut(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    whole = _recording(
        tmp_path / "whole.mcap", [_learned(2, "sandy", SANDY.id, 0.31), _learned(25, "muddy", MUDDY.id, 0.2)]
    )
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(whole.read_bytes()[: whole.stat().st_size // 2])
    read = read_learned([cut])
    assert [x.class_name for x in read.learnings] == ["sandy"] and cut in read.stops
    assert main(["logs", "learned", str(cut)]) == 1
    captured = capsys.readouterr()
    assert _beliefs(captured.out) == {"sandy": 0.31}  # the tables on stdout
    assert f"{cut} is cut short at byte" in captured.err


def test_a_file_that_is_no_recording_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = tmp_path / "not.mcap"
    source.write_bytes(b"not an mcap file at all")
    out = tmp_path / "t.toml"
    assert main(["logs", "learned", str(source), "--out", str(out)]) == 2
    assert not out.exists()
    assert "not.mcap" in " ".join(capsys.readouterr().err.split())


@pytest.mark.parametrize(
    ("bad", "named"),
    [
        ({"class_name": "gravel2"}, "no terrain class 'gravel2'"),  # a newer build's class
        ({"field": "slip_limit"}, "'slip_limit' is no field of a terrain class table"),
        ({"value": -0.1}, "a rover config would refuse it"),  # the class check's own refusal
    ],
    ids=["unknown-class", "unknown-field", "refused-value"],
)
def test_what_a_rover_config_would_refuse_is_refused_not_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], bad: dict[str, Any], named: str
) -> None:
    """Tables the config loader refuses are no tables: `rover logs learned` wrote them, exit 0."""
    source = _recording(
        tmp_path / "r.mcap",
        [{**_learned(3, "sandy", SANDY.id, 0.2), **bad}, _learned(9, "sandy", SANDY.id, 0.33)],
    )
    read = read_learned([source], check=override_refusal)
    assert len(read.refused) == 1 and named in read.refused[0]
    out = tmp_path / "t.toml"
    assert main(["logs", "learned", str(source), "--out", str(out)]) == 1
    assert named in " ".join(capsys.readouterr().err.split())
    assert _beliefs(out.read_text()) == {"sandy": 0.33}  # loads: the refused one is not in it


def test_times_are_from_the_recordings_first_message_and_folders_are_read_whole(tmp_path: Path) -> None:
    """A `rover run` recording's log time is the computer's monotonic clock: 1000 s into it here."""
    late = 1_000_000_000_000
    path = tmp_path / "campaign" / "sandy" / "run.mcap"
    path.parent.mkdir(parents=True)
    with McapRecorder(path) as recorder:
        recorder.publish(NAVIGATOR_STATE, late, {"timestamp": stamp(late), "mode": "DRIVING"})
        learned = _learned(0, "sandy", SANDY.id, 0.3)
        recorder.publish(NAVIGATOR_LEARNED, late + 23_040_000_000, learned)
    assert read_learned([path]).learnings[0].t_s == pytest.approx(23.04)
    out = tmp_path / "t.toml"
    assert main(["logs", "learned", str(tmp_path / "campaign"), "--out", str(out)]) == 0
    assert f"# {path} at 23.04 s" in out.read_text() and _beliefs(out.read_text()) == {"sandy": 0.3}


def test_a_path_with_a_line_break_stays_in_its_comment(tmp_path: Path) -> None:
    source = _recording(tmp_path / "odd\nname.mcap", [_learned(5, "sandy", SANDY.id, 0.3)])
    assert _beliefs(learned_tables(read_learned([source]))) == {"sandy": 0.3}
