"""``rover logs csv``: one CSV per topic, fields flattened, values as recorded; bad input named."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from logs.csv_export import CsvExportError, export_csv, file_name_for, flatten
from logs.errors import LogReadError
from logs.reader import RecordedMessage, read_messages
from logs.recorder import McapRecorder
from logs.synthetic import synthetic_metadata, write_synthetic_trial
from rover_cli.main import main


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("csv") / "trial.mcap"
    with McapRecorder(path) as recorder:
        recorder.add_metadata("scenario", synthetic_metadata(4.0))
        write_synthetic_trial(recorder, 4.0)
    return path


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def test_flatten_spreads_short_lists_keeps_long_ones_whole_and_spells_non_finite() -> None:
    cells = flatten({"a": {"b": 1, "c": [1.5, 2.5]}, "path": list(range(40)), "x": math.nan, "ok": True})
    assert cells == {"a.b": 1, "a.c.0": 1.5, "a.c.1": 2.5, "path": "[" + ",".join(map(str, range(40))) + "]",
                     "x": "nan", "ok": True}  # fmt: skip


def test_file_names_are_safe_and_never_clash() -> None:
    assert file_name_for("truth/pose", set()) == "truth.pose.csv"
    assert file_name_for("../../etc/passwd", set()) == "etc.passwd.csv"
    assert file_name_for("a b/c", {"a_b.c.csv"}) == "a_b.c-2.csv"


def test_every_topic_becomes_a_csv_with_the_recorded_values(recording: Path, tmp_path: Path) -> None:
    result = export_csv(recording, tmp_path / "csv")
    recorded: dict[str, list[RecordedMessage]] = {}
    for message in read_messages(recording):
        recorded.setdefault(message.topic, []).append(message)
    assert set(result.files) == set(recorded)
    for topic, messages in recorded.items():
        rows = _rows(result.files[topic])
        assert len(rows) == result.rows[topic] == len(messages)
        first, cells = rows[0], flatten(messages[0].message)
        assert int(first["log_time_ns"]) == messages[0].log_time_ns
        assert float(first["log_time_s"]) == pytest.approx(messages[0].log_time_ns / 1e9)
        for column, value in cells.items():
            if isinstance(value, float):
                assert float(first[column]) == pytest.approx(value, rel=1e-12), (topic, column)
            elif value is not None:
                assert first[column] == str(value), (topic, column)
    assert not result.truncated


def test_a_topic_subset_and_an_unknown_topic(recording: Path, tmp_path: Path) -> None:
    result = export_csv(recording, tmp_path / "one", ["truth/pose"])
    assert list(result.files) == ["truth/pose"] and [p.name for p in (tmp_path / "one").iterdir()] == [
        "truth.pose.csv"
    ]
    with pytest.raises(CsvExportError, match="no topic truth/posse"):
        export_csv(recording, tmp_path / "two", ["truth/posse"])
    assert not (tmp_path / "two").exists()


def test_cli_exit_codes(recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["logs", "csv", str(recording), "--out", str(tmp_path / "ok"), "--topics", "truth/pose"]) == 0
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(recording.read_bytes()[: recording.stat().st_size // 2])
    assert main(["logs", "csv", str(cut), "--out", str(tmp_path / "cut")]) == 1  # the readable part, said
    assert "cut short" in " ".join(capsys.readouterr().out.split())
    assert any(_rows(p) for p in (tmp_path / "cut").iterdir())
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"PK\x03\x04 a zip file")
    assert main(["logs", "csv", str(junk), "--out", str(tmp_path / "junk")]) == 2
    assert "not an MCAP file" in " ".join(capsys.readouterr().out.split())
    with pytest.raises(LogReadError):
        export_csv(junk, tmp_path / "junk2")
    blocked = tmp_path / "file"
    blocked.write_text("")
    assert main(["logs", "csv", str(recording), "--out", str(blocked / "sub")]) == 2
