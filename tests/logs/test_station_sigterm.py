"""`rover telemetry record` stopped with SIGTERM (systemd, docker) closes its recording as Ctrl-C does."""

import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from logs.doctor import diagnose


def _free_tcp_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.mark.realtime
def test_sigterm_leaves_a_complete_recording(tmp_path: Path) -> None:
    out = tmp_path / "station.mcap"
    station = subprocess.Popen(
        [sys.executable, "-m", "rover_cli.main", "telemetry", "record", str(out),
         "--connect", f"tcp/127.0.0.1:{_free_tcp_port()}", "--duration-s", "60"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 30
        while not out.exists() and time.monotonic() < deadline:  # the recorder has opened its file
            time.sleep(0.1)
        time.sleep(0.5)
        station.send_signal(signal.SIGTERM)
        output, _ = station.communicate(timeout=30)
    finally:
        station.kill()
    # Nobody published (exit 1, "heard nothing", as watch says it), but the recording is whole all the same;
    # its one problem is that it holds no message (doctor calls no recording without one healthy).
    assert station.returncode == 1 and "heard nothing" in output, output
    report = diagnose(out)
    assert report.complete and report.footer_present and report.cut_at is None, report
    assert [problem.split(":")[0] for problem in report.problems] == ["no messages"], report
