"""Two real processes for real-time HIL tests: ``rover hil peer`` and ``rover run``, on real wires.

CAN is python-can ``udp_multicast`` (only inside the private network namespace that
``scripts/in-private-netns`` makes, which sets ``ROVER_IN_NETNS=1``) or ``socketcan``/``vcan0`` where the
kernel has it; MAVLink is UDP on 127.0.0.1 on a port the peer's OS picked. Every process is stopped when
the ``with`` block ends, whatever happened inside.
"""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import pytest

IN_NETNS = os.environ.get("ROVER_IN_NETNS") == "1"
needs_netns = pytest.mark.skipif(
    not IN_NETNS,
    reason="python-can udp_multicast runs only inside a private loopback-only network namespace "
    "(scripts/in-private-netns, which `make test` uses, sets ROVER_IN_NETNS=1)",
)
HAS_VCAN = Path("/sys/class/net/vcan0").exists()
needs_vcan = pytest.mark.skipif(not HAS_VCAN, reason="no vcan0: this kernel has no SocketCAN / vcan support")

# A fresh group per run, so a peer left over from another test can never talk to this one's rover.
_groups = itertools.count(1)
# Start-up of `rover run` includes compiling the A* kernel when numba's cache misses (seconds to tens of
# seconds on a loaded machine), so readiness waits are generous; the drive itself is timed separately.
START_TIMEOUT_S = 120.0

T = TypeVar("T")


def fresh_multicast_group() -> str:
    n = next(_groups)
    return f"239.74.{(os.getpid() >> 8) % 200 + 10}.{(os.getpid() + n) % 250 + 1}"


@dataclass
class Peer:
    process: subprocess.Popen[bytes]
    out_dir: Path
    status_file: Path
    rover_config: Path

    def status(self) -> dict[str, Any] | None:
        try:
            return dict(json.loads(self.status_file.read_text(encoding="utf-8")))
        except (FileNotFoundError, json.JSONDecodeError):
            return None


def _text(path: Path) -> str | None:
    return path.read_text(encoding="utf-8").strip() or None if path.exists() else None


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "rover_cli.main", *args]


def _stop(process: subprocess.Popen[bytes], how: int = signal.SIGINT) -> None:
    if process.poll() is not None:
        return
    process.send_signal(how)
    try:
        process.wait(timeout=20)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(timeout=10)


def wait_for(
    check: Callable[[], T | None], timeout_s: float, what: str, *processes: subprocess.Popen[bytes]
) -> T:
    """Poll ``check`` until it returns something; fail naming ``what`` on timeout or a process exiting."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = check()
        if value is not None:
            return value
        for process in processes:
            if process.poll() is not None:
                pytest.fail(f"waiting for {what}: {process.args!r} exited with {process.returncode}")
        time.sleep(0.05)
    pytest.fail(f"timed out after {timeout_s:g} s waiting for {what}")


@contextmanager
def running_peer(scenario: Path, out_dir: Path, interface: str, channel: str) -> Iterator[Peer]:
    out_dir.mkdir(parents=True, exist_ok=True)
    port_file = out_dir / "port"
    status_file = out_dir / "status.json"
    with open(out_dir / "peer.log", "wb") as log:
        process = subprocess.Popen(
            _cli(
                "hil",
                "peer",
                str(scenario),
                "--can-interface",
                interface,
                "--can-channel",
                channel,
                "--port-file",
                str(port_file),
                "--status-file",
                str(status_file),
                "--out",
                str(out_dir),
                "--duration",
                "300",
            ),
            stdout=log,
            stderr=subprocess.STDOUT,
        )
        try:
            wait_for(lambda: _text(port_file), 60.0, "the peer's port file", process)
            yield Peer(process, out_dir, status_file, out_dir / "rover-hil.toml")
        finally:
            _stop(process)


@contextmanager
def running_rover(
    config: Path, goal: tuple[float, float], out_dir: Path
) -> Iterator[subprocess.Popen[bytes]]:
    out_dir.mkdir(parents=True, exist_ok=True)
    with open(out_dir / "rover.log", "wb") as log:
        process = subprocess.Popen(
            _cli(
                "-v", "run", "--config", str(config), "--goal", f"{goal[0]},{goal[1]}", "--out", str(out_dir)
            ),
            stdout=log,
            stderr=subprocess.STDOUT,
        )
        try:
            yield process
        finally:
            if process.poll() is None:
                os.kill(process.pid, signal.SIGCONT)  # a stopped process cannot act on SIGINT
            _stop(process)
