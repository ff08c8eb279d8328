"""``rover logs doctor|recover|report`` exit codes and outputs on a small synthetic recording."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from mcap.writer import Writer

from logs.doctor import diagnose
from logs.errors import NotARecording
from logs.reader import ReadStats, read_entries
from rover_cli.main import main
from tests.logs.damaged_recording import damage_a_middle_chunk, write_small_trial


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_small_trial(tmp_path_factory.mktemp("cli") / "trial.mcap")


def test_doctor_exit_codes(recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["logs", "doctor", str(recording), "--json"]) == 0
    findings = json.loads(capsys.readouterr().out)
    assert findings["healthy"] and findings["topics"]["can/frames"]["messages"] == 14 * 200
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(recording.read_bytes()[: recording.stat().st_size // 2])
    assert main(["logs", "doctor", str(cut)]) == 1
    assert "cut short" in " ".join(capsys.readouterr().out.split())  # rich wraps long lines
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"PK\x03\x04 a zip file")
    assert main(["logs", "doctor", str(junk)]) == 2
    assert "not an MCAP file" in " ".join(capsys.readouterr().out.split())


def test_recover_then_report(recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(recording.read_bytes()[: recording.stat().st_size // 2])
    assert main(["logs", "recover", str(cut), str(tmp_path / "fixed.mcap"), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["messages"] > 0 and not result["was_complete"]
    assert (
        main(["logs", "report", str(tmp_path / "fixed.mcap"), "--out", str(tmp_path / "r"), "--no-plots"])
        == 0
    )
    assert (tmp_path / "r" / "report.html").exists() and (tmp_path / "r" / "report.json").exists()
    assert main(["logs", "report", str(tmp_path / "absent.mcap"), "--out", str(tmp_path / "r2")]) == 2


def test_report_exit_codes_say_whether_every_input_made_it(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")  # a recorder that died before its first byte
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(damage_a_middle_chunk(recording.read_bytes())[0])
    out = ["--out", str(tmp_path / "r"), "--no-plots"]
    # A report of the good file, without the two others: 1, each named with why, and where to look next:
    # recover for the damaged one only (the empty one holds nothing to recover).
    assert main(["logs", "report", str(recording), str(empty), str(damaged), *out]) == 1
    printed = " ".join(capsys.readouterr().out.split())
    assert "empty.mcap: holds no messages" in printed and "damaged.mcap: " in printed
    assert f"`rover logs recover FILE OUT` keeps every complete chunk of {damaged}," in printed
    assert main(["logs", "report", str(recording), str(empty), *out]) == 1
    assert "rover logs recover" not in capsys.readouterr().out
    # Nothing readable at all: 2, and no report of nothing.
    assert main(["logs", "report", str(empty), "--out", str(tmp_path / "none")]) == 2
    assert not (tmp_path / "none").exists()
    assert main(["logs", "report", str(recording), *out]) == 0


@pytest.mark.parametrize("content", [b"", b"\x89MCAP"], ids=["empty", "5-bytes"])
def test_recover_of_a_file_with_nothing_to_keep_is_an_error_without_output(
    content: bytes, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = tmp_path / "died.mcap"
    source.write_bytes(content)
    out = tmp_path / "rescued.mcap"
    assert main(["logs", "recover", str(source), str(out)]) == 2
    printed = " ".join(capsys.readouterr().out.split())
    assert f"nothing recoverable in {source}" in printed
    assert not out.exists()


@pytest.mark.parametrize("content", [b"", b"\x89MCAP"], ids=["empty", "5-bytes"])
def test_doctor_calls_a_file_with_no_recording_in_it_bad_input(
    content: bytes, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # As `rover can export` and `rover logs csv` do: it is not a recording cut short that recover could help.
    source = tmp_path / "died.mcap"
    source.write_bytes(content)
    with pytest.raises(NotARecording, match="no recording in it"):
        diagnose(source)
    assert main(["logs", "doctor", str(source)]) == 2
    assert f"{source} " in (printed := " ".join(capsys.readouterr().out.split()))
    assert "no recording in it" in printed and "rover logs recover" not in printed


def test_doctor_words_a_cut_and_damage_as_the_exports_do(recording: Path, tmp_path: Path) -> None:
    content, damaged_at = damage_a_middle_chunk(recording.read_bytes())
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(content)
    assert f"chunk damaged at byte {damaged_at} (" in " ".join(diagnose(damaged).problems)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(content[: damaged_at + 20])
    findings = diagnose(cut)
    stop = ReadStats()
    list(read_entries(cut, stats=stop))
    assert stop.stop is not None and findings.cut_at == stop.stop.offset == damaged_at
    assert f"is {stop.stop.describe()}" in " ".join(findings.problems)


LONG_TOPIC = "/robot/sensors/front_left_stereo_camera/image_rectified/compressed_depth"


def _foreign_recording(path: Path) -> Path:
    """An MCAP from another tool: one JSON topic with a long ROS-style name, on a clock far from zero."""
    with path.open("wb") as handle:
        writer = Writer(handle)
        writer.start(profile="", library="other-tool")
        schema = writer.register_schema(name="Depth", encoding="jsonschema", data=b'{"type":"object"}')
        channel = writer.register_channel(topic=LONG_TOPIC, message_encoding="json", schema_id=schema)
        for i in range(3):
            t = 1_700_000_000_000_000_000 + i * 123_456_789_012
            writer.add_message(channel_id=channel, log_time=t, publish_time=t, data=b'{"v": 1}')
        writer.finish()
    return path


def test_doctor_and_csv_tables_piped_to_a_file_keep_every_name_whole(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Piped (`rover logs doctor F > out.txt`), rich fitted the tables to 80 columns and cut the topic
    and the CSV file's path with '…': '/robot/sensors/fron…', 'csv/robot.sensors.front_left_s…'."""
    monkeypatch.setenv("COLUMNS", "80")  # what rich assumes for a pipe
    recording = _foreign_recording(tmp_path / "foreign.mcap")
    assert main(["logs", "doctor", str(recording)]) == 0
    printed = capsys.readouterr().out
    assert "…" not in printed
    row = next(line for line in printed.splitlines() if LONG_TOPIC in line)
    assert "1700000246.914" in row  # the whole row on one line: topic, count, first and last time
    out = tmp_path / "a" / "long" / "folder" / "for" / "the" / "csv" / "files"
    assert main(["logs", "csv", str(recording), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    (written,) = out.iterdir()
    assert "…" not in printed and str(written) in printed


def test_csv_help_says_what_the_files_hold(capsys: pytest.CaptureFixture[str]) -> None:
    """It said "for pandas", which the venv does not have: it says what the columns are."""
    from logs.csv_export import MAX_SPREAD_LIST

    for command in (["logs", "--help"], ["logs", "csv", "--help"]):
        with pytest.raises(SystemExit):
            main(command)
        printed = " ".join(capsys.readouterr().out.split())
        assert "log_time_ns, log_time_s, then the message's fields flattened with dots" in printed, command
        assert "pandas" not in printed
    assert f"a list of up to {MAX_SPREAD_LIST} items over indexed columns" in printed
