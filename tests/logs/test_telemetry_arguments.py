"""``rover telemetry`` with arguments a person gets wrong: exit 2 and a line naming what, never a traceback;
and a station that reached nothing says how to reach the rover."""

from __future__ import annotations

from pathlib import Path

import pytest

from rover_cli.main import main

# Each station command, run briefly (`record` into station.mcap in the current folder).
EACH_COMMAND = pytest.mark.parametrize(
    "command",
    [
        ["watch", "--duration-s", "0.1"],
        ["record", "station.mcap", "--duration-s", "0.1"],
        ["send", "estop", "--timeout-s", "0.1"],
    ],
    ids=lambda c: c[0],
)


def _out(capsys: pytest.CaptureFixture[str]) -> str:
    captured = capsys.readouterr()
    return " ".join((captured.out + captured.err).split())


@EACH_COMMAND
@pytest.mark.parametrize(
    ("config_text", "said"),
    [(None, "file not found"), ("rover_id = 5\n", "rover_id: expected a string")],
    ids=["missing", "bad"],
)
def test_a_config_that_cannot_be_used_is_exit_2_naming_it(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    command: list[str],
    config_text: str | None,
    said: str,
) -> None:
    monkeypatch.chdir(tmp_path)
    config = tmp_path / "station.toml"
    if config_text is not None:
        config.write_text(config_text)
    code = main(["telemetry", *command, "--config", str(config)])
    out = _out(capsys)
    assert code == 2, out
    assert f"--config: {config}" in out and said in out, out
    assert not (tmp_path / "station.mcap").exists()


@pytest.mark.parametrize("xy", [["nan", "2"], ["1", "inf"]])
def test_a_goal_that_is_not_finite_is_refused_before_anything_is_sent(
    capsys: pytest.CaptureFixture[str], xy: list[str]
) -> None:
    code = main(["telemetry", "send", "goal", *xy, "--connect", "tcp/127.0.0.1:9", "--timeout-s", "0.1"])
    out = _out(capsys)
    assert code == 2, out
    assert "goal x y must be finite numbers" in out, out
    assert "NOT confirmed" not in out


def test_a_station_with_nothing_to_connect_to_says_to_give_connect(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code = main(["telemetry", "send", "resume", "--timeout-s", "0.2"])
    out = _out(capsys)
    assert code == 1, out
    assert "connected to no Zenoh peer or router" in out and "no --connect given" in out, out


@EACH_COMMAND
@pytest.mark.parametrize("rover_id", ["a/b", "rover*", ""])
def test_a_rover_id_that_cannot_name_a_key_is_exit_2_naming_it(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    command: list[str],
    rover_id: str,
) -> None:
    # `watch` and `record` had ended in a TelemetrySetupError traceback from the subscription, and `record`
    # had left station.mcap behind, created before the subscription failed.
    monkeypatch.chdir(tmp_path)
    code = main(["telemetry", *command, "--rover-id", rover_id, "--connect", "tcp/127.0.0.1:9"])
    out = _out(capsys)
    assert code == 2, out
    assert f"--rover-id: rover_id {rover_id!r} cannot name a Zenoh key" in out, out
    assert not (tmp_path / "station.mcap").exists()


def test_record_leaves_an_earlier_recording_as_it_is(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # `rover telemetry record station.mcap` run twice had emptied the first station recording (the
    # recorder opens its file for writing), with exit 0.
    earlier = tmp_path / "station.mcap"
    earlier.write_bytes(b"an earlier station recording")
    code = main(["telemetry", "record", str(earlier), "--connect", "tcp/127.0.0.1:9", "--duration-s", "0.1"])
    out = _out(capsys)
    assert code == 2, out
    assert f"{earlier} already exists" in out, out
    assert earlier.read_bytes() == b"an earlier station recording"


@pytest.mark.parametrize(
    "command", [["watch", "--duration-s", "0.2"], ["send", "estop", "--timeout-s", "0.2"]], ids=lambda c: c[0]
)
def test_the_hint_for_a_station_that_reached_nothing_is_printed_as_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: list[str]
) -> None:
    # "does --config X's [zenoh] connect name the rover" had come out as "does --config X's  connect name
    # the rover": rich read "[zenoh]" as markup and dropped it, and with it the table the user must edit.
    config = tmp_path / "station[1].toml"
    config.write_text('rover_id = "rover1"\n', encoding="utf-8")
    code = main(["telemetry", *command, "--config", str(config)])
    out = _out(capsys)
    assert code == 1, out
    # Compared without whitespace: rich wraps a long path (a pytest worker's tmp path) wherever it likes.
    expected = f"does --config {config}'s [zenoh] connect name the rover"
    assert "".join(expected.split()) in "".join(out.split()), out
