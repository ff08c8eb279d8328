"""``rover run``'s console lines: a reader of its stdout that goes away must not stop the rover."""

from __future__ import annotations

import logging
import os
import sys

import pytest

from rover_cli import run_commands


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
