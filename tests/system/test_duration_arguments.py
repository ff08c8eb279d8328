"""Durations and goal points on the command line: nan, inf, 0 or a negative value is refused by argparse
(usage, exit 2) before anything opens; ``rover run --duration nan`` had ended in a traceback and
``--duration 0`` had run no tick and exited 0."""

from __future__ import annotations

from pathlib import Path

import pytest

from rover_cli.main import main

DATA = Path(__file__).resolve().parents[1] / "data"
REPO = Path(__file__).resolve().parents[2]
HARDWARE = REPO / "configs" / "rover.example-hardware.toml"

COMMANDS = [
    ["run", "--config", str(HARDWARE), "--duration"],
    ["hil", "peer", str(DATA / "small_rocky.toml"), "--duration"],
    ["telemetry", "watch", "--duration-s"],
    ["telemetry", "record", "station.mcap", "--duration-s"],
]


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: " ".join(c[:2]))
@pytest.mark.parametrize("value", ["nan", "inf", "0", "-1"])
def test_a_duration_that_is_not_a_positive_number_of_seconds_is_refused(
    command: list[str],
    value: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.chdir(tmp_path)
    argv = [*command, value]
    if command[0] in ("run", "hil"):
        argv += ["--out", str(tmp_path / "out")]
    with pytest.raises(SystemExit) as stopped:
        main(argv)
    assert stopped.value.code == 2
    error = capsys.readouterr().err
    assert command[-1] in error and repr(value) in error, error
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("goal", ["nan,1", "1,inf"])
def test_rover_run_refuses_a_goal_that_is_not_finite(
    goal: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as stopped:
        main(["run", "--config", str(HARDWARE), "--goal", goal, "--out", str(tmp_path / "out")])
    assert stopped.value.code == 2
    assert "finite" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
