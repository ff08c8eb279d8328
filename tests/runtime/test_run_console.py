"""``rover run``'s console lines: a reader of its stdout that goes away must not stop the rover."""

from __future__ import annotations

import logging
import os
import sys
import threading
from pathlib import Path

import pytest

from logs.clock import MonotonicClock
from logs.settings import parse_toml
from navigator.config import load_rover_config, rover_config_from_table
from navigator.rover_process import loop_phrase, run_rover
from rover_cli import run_commands
from tests.runtime.run_config import rover_run_config


def test_a_stdout_reader_gone_stops_the_lines_not_the_run(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    # `rover run ... | head -2`: the third line, printed from the control loop's first tick, raised
    # BrokenPipeError there; the run stopped with exit 1 and "rover run failed: BrokenPipeError" in its
    # recording, before it ever drove. The lines are on safety/events too: the run must go on without them.
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone
    with os.fdopen(write_end, "w") as stream:
        monkeypatch.setattr(sys, "stdout", stream)
        with caplog.at_level(logging.WARNING, logger=run_commands.__name__):
            run_commands._announce(
                "start-up checks pending: no autopilot heartbeat; not driving until they pass"
            )
            run_commands._announce("start-up checks passed: ...; driving allowed")
            run_commands._announce("recording: /tmp/x/rover.mcap")
        said = " ".join(caplog.text.split())
        assert "stdout's reader went away" in said and "the run goes on" in said
        assert caplog.text.count("reader went away") == 1  # said once, not per line


@pytest.mark.parametrize(
    ("settings", "phrase"),
    [
        ("", "phase-locked 0.3 ms after imu"),
        ('control_loop = "sensor-paced"', "paced by imu"),
        ('pacing_sensor = "none"', "fixed-rate, no pacing sensor"),
        ('pacing_sensor = "none"\ncontrol_loop = "sensor-paced"', "fixed-rate, no pacing sensor"),
    ],
)
def test_the_warm_up_line_names_the_loop_that_runs(settings: str, phrase: str) -> None:
    # `pacing_sensor = "none"` printed "running at 25 Hz, phase-locked 0.3 ms after none": no sensor paces
    # that loop, which runs on its own fixed-rate grid (docs/runtime.md).
    config = rover_config_from_table(parse_toml(settings, "<test>"))
    assert loop_phrase(config) == phrase


def test_a_stop_asked_during_the_warm_up_is_said_instead_of_the_running_line(tmp_path: Path) -> None:
    # SIGTERM during a 27 s cold warm-up: "signal SIGTERM: stopping", then "warm-up done in 27.3 s; rover
    # rover1 running at 50 Hz, ...; driving waits for the start-up checks (next line ...)", and no next
    # line but "recording: ... 0 ticks". The line must say the run is stopping, not that it runs.
    config_path = tmp_path / "rover.toml"
    config_path.write_text(rover_run_config("warmstop", "warmstop-0"), encoding="utf-8")
    stop = threading.Event()
    stop.set()
    said: list[str] = []
    result = run_rover(
        load_rover_config(config_path),
        MonotonicClock(),
        tmp_path / "run",
        stop=stop,
        telemetry=False,
        announce=said.append,
    )
    assert result.timing.ticks == 0
    warm_up_line = next(line for line in said if line.startswith("warm-up done in "))
    assert "stopping: a stop was asked during the warm-up" in warm_up_line
    assert "running at" not in warm_up_line and "next line" not in warm_up_line
