"""``rover logs csv``: one CSV per topic, fields flattened, values as recorded; bad input named."""

from __future__ import annotations

import csv
import math
from io import BytesIO
from pathlib import Path

import pytest
from mcap.writer import Writer

from logs.csv_export import CsvExportError, export_csv, file_name_for, flatten
from logs.errors import LogReadError, NotARecording
from logs.read_stop import DAMAGED
from logs.reader import RecordedMessage, read_messages
from rover_cli.main import main
from tests.logs.damaged_recording import damage_a_middle_chunk, write_small_trial


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_small_trial(tmp_path_factory.mktemp("csv") / "trial.mcap")


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
    assert "cut short at byte" in capsys.readouterr().err
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


def test_a_recording_damaged_partway_exports_what_comes_before_the_damage(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    content, damaged_at = damage_a_middle_chunk(recording.read_bytes())
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(content)
    before = list(read_messages(BytesIO(content[:damaged_at])))  # what a cut at the damage would read
    result = export_csv(damaged, tmp_path / "csv")
    assert result.stop is not None and (result.stop.kind, result.stop.offset) == (DAMAGED, damaged_at)
    assert sum(result.rows.values()) == len(before) > 0
    assert main(["logs", "csv", str(damaged), "--out", str(tmp_path / "cli")]) == 1
    err = capsys.readouterr().err
    assert f"{damaged} is damaged at byte {damaged_at}" in err
    assert f"the CSV files in {tmp_path / 'cli'} hold the {len(before)} messages before it" in err


@pytest.mark.parametrize("content", [b"", b"\x89MCAP"], ids=["empty", "5-bytes"])
def test_a_file_with_no_recording_in_it_is_an_error_and_writes_nothing(
    content: bytes, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = tmp_path / "died.mcap"
    source.write_bytes(content)
    with pytest.raises(NotARecording, match="no recording in it"):
        export_csv(source, tmp_path / "csv")
    assert main(["logs", "csv", str(source), "--out", str(tmp_path / "cli")]) == 2
    assert "no recording in it" in " ".join(capsys.readouterr().out.split())
    assert not (tmp_path / "csv").exists() and not (tmp_path / "cli").exists()


def _foreign(path: Path) -> Path:
    """An MCAP from another tool: a CDR topic (ROS 2) beside one JSON topic, 3 messages each."""
    with path.open("wb") as handle:
        writer = Writer(handle)
        writer.start(profile="ros2", library="other-tool")
        cdr = writer.register_schema(name="nav_msgs/msg/Odometry", encoding="ros2msg", data=b"float64 x")
        json_schema = writer.register_schema(name="Odom", encoding="jsonschema", data=b'{"type":"object"}')
        odom = writer.register_channel(topic="/odom", message_encoding="cdr", schema_id=cdr)
        fix = writer.register_channel(topic="/fix", message_encoding="json", schema_id=json_schema)
        for i in range(3):
            writer.add_message(channel_id=odom, log_time=i, publish_time=i, data=bytes(16))
            writer.add_message(channel_id=fix, log_time=i, publish_time=i, data=b'{"lat": 47.0}')
        writer.finish()
    return path


def test_a_topic_that_could_not_be_exported_is_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`rover logs csv ros.mcap --out DIR --topics /odom` printed an empty table and "skipped 3 message(s)
    that could not be decoded", naming no topic: which topic got no CSV was left to guess."""
    source = _foreign(tmp_path / "ros.mcap")
    result = export_csv(source, tmp_path / "all")
    assert result.rows == {"/fix": 3} and result.undecodable == {"/odom": 3}
    assert main(["logs", "csv", str(source), "--out", str(tmp_path / "odom"), "--topics", "/odom"]) == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert "skipped 3 message(s) that could not be decoded: /odom 3 of 3 (no CSV)" in printed
