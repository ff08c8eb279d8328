"""CanLink against the simulated VESC controllers, written once and run over every bus we support.

- ``virtual``: both ends in this process, lockstep on a simulated clock.
- ``udp_multicast``: the controllers run in a second process, in real time; only inside the private
  network namespace (``make test`` / ``scripts/in-private-netns``), where multicast cannot leave lo.
- ``socketcan``: vcan0, controllers in a second process; only where the kernel offers vcan0
  (``scripts/setup-vcan.sh``).
"""

from __future__ import annotations

import os
import select
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import can
import pytest

from firmware_bridge.can_link import CanLink
from hil.vesc_sim import SimVescBank
from logs.can_load import frame_bits
from logs.clock import Clock, MonotonicClock, SimClock, to_ns
from logs.sink import MemorySink
from logs.topics import CAN_FRAMES, SAFETY_EVENTS
from tests.firmware_bridge.virtual_can import make_codec, virtual_bus_pair

REPO = Path(__file__).resolve().parents[2]
STEP_S = 0.02
UDP_GROUP = "239.74.163.2"  # python-can's IPv4 default group; only ever joined inside the private netns
VCAN = "vcan0"
TARGETS_MPS = [0.5, 0.5, 0.5, -0.3, -0.3, -0.3]


class Peer(Protocol):
    """The controllers' side: lets ``dt`` seconds pass for them; ``stop()`` silences them."""

    def advance(self, dt_s: float) -> None: ...

    def stop(self) -> None: ...


@dataclass
class Rig:
    bus: can.BusABC
    clock: Clock
    peer: Peer


class InProcessPeer:
    def __init__(self, bus: can.BusABC, clock: SimClock) -> None:
        self._bank = SimVescBank(bus, make_codec(), clock)
        self._clock = clock
        self._running = True

    def advance(self, dt_s: float) -> None:
        if self._running:
            self._bank.poll()
            self._bank.step(dt_s)
        self._clock.advance(to_ns(dt_s))

    def stop(self) -> None:
        self._running = False


class ProcessPeer:
    """``tests.firmware_bridge.vesc_peer`` in a subprocess; real time passes by itself."""

    def __init__(self, interface: str, channel: str, port: int | None) -> None:
        args = [sys.executable, "-m", "tests.firmware_bridge.vesc_peer", interface, channel]
        if port is not None:
            args.append(str(port))
        self._process = subprocess.Popen(
            args, cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        assert self._process.stdout is not None
        ready, _, _ = select.select([self._process.stdout], [], [], 30.0)
        line = self._process.stdout.readline() if ready else b""
        if line.strip() != b"ready":
            self.stop()
            pytest.fail(f"the VESC peer process did not start: {line!r}")

    def advance(self, dt_s: float) -> None:
        time.sleep(dt_s)  # pacing real time at the command rate, not synchronisation

    def stop(self) -> None:
        if self._process.poll() is None:
            _, errors = self._process.communicate(timeout=10.0)  # closes stdin: the peer's stop signal
            assert self._process.returncode == 0, errors.decode(errors="replace")


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture(params=["virtual", "udp_multicast", "socketcan"])
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    kind = request.param
    if kind == "virtual":
        clock = SimClock(1_000_000_000)
        with virtual_bus_pair(request.node.name) as (ours, theirs):
            yield Rig(ours, clock, InProcessPeer(theirs, clock))
        return
    if kind == "udp_multicast":
        if os.environ.get("ROVER_IN_NETNS") != "1":
            pytest.skip(
                "udp_multicast runs only inside a private network namespace (ROVER_IN_NETNS=1); use "
                "`make test` or `scripts/in-private-netns .venv/bin/pytest ...`"
            )
        port = free_udp_port()
        bus = can.Bus(interface="udp_multicast", channel=UDP_GROUP, port=port, ignore_config=True)
        channel: str = UDP_GROUP
    else:
        if not Path(f"/sys/class/net/{VCAN}").exists():
            pytest.skip(f"no {VCAN} here: this kernel has no SocketCAN/vcan (see scripts/setup-vcan.sh)")
        port = None
        bus = can.Bus(interface="socketcan", channel=VCAN, ignore_config=True)
        channel = VCAN
    peer = None
    try:
        peer = ProcessPeer(kind, channel, port)
        yield Rig(bus, MonotonicClock(), peer)
    finally:
        if peer is not None:
            peer.stop()
        bus.shutdown()


def drive(link: CanLink, rig: Rig, steps: int, until: Callable[[], bool]) -> bool:
    """Command the targets each step until ``until()``; False if it never held within ``steps``."""
    for _ in range(steps):
        link.send_wheel_speeds(TARGETS_MPS)
        rig.peer.advance(STEP_S)
        link.poll()
        if until():
            return True
    return False


def test_wheels_follow_commands_over_the_bus(rig: Rig) -> None:
    sink = MemorySink()
    with CanLink(rig.bus, make_codec(), rig.clock, sink) as link:

        def converged() -> bool:
            speeds = [r.speed_mps for r in link.readings()]
            return all(abs(s - t) < 0.01 for s, t in zip(speeds, TARGETS_MPS, strict=True))

        assert drive(link, rig, 150, converged), [r.speed_mps for r in link.readings()]
        assert all(link.controllers_alive().values())
        assert all(
            r.last_status_ns is not None and r.input_voltage_v == pytest.approx(24.0) for r in link.readings()
        )
        counters = link.counters
        assert counters.tx >= 6 and counters.rx >= 18
        assert counters.unknown_id == counters.wrong_dlc == counters.decode_errors == counters.bus_errors == 0


def test_silent_controllers_are_reported_dead(rig: Rig) -> None:
    sink = MemorySink()
    link = CanLink(rig.bus, make_codec(), rig.clock, sink)
    try:
        assert drive(link, rig, 150, lambda: all(r.last_status_ns is not None for r in link.readings()))
        rig.peer.stop()
        assert drive(link, rig, 50, lambda: not any(link.controllers_alive().values()))
        kinds = [event["kind"] for event in sink.on(SAFETY_EVENTS)]
        assert kinds, "a silent controller must leave a safety event"
    finally:
        link.close()


def test_each_frame_on_the_wire_is_counted_and_recorded_once(rig: Rig) -> None:
    """udp_multicast delivers our own sends back to us: they must not come back as received frames."""
    sink = MemorySink()
    with CanLink(rig.bus, make_codec(), rig.clock, sink) as link:
        assert drive(link, rig, 150, lambda: all(r.last_status_ns is not None for r in link.readings()))
        frames = sink.on(CAN_FRAMES)
        sent_ids = {f["id"] for f in frames if f["direction"] == "tx"}
        received = [f for f in frames if f["direction"] == "rx"]
        assert sent_ids and received
        assert not [f for f in received if f["id"] in sent_ids], "our own commands came back as rx"
        counters = link.counters
        assert counters.tx == len(frames) - len(received) and counters.rx == len(received)
        assert link.bits_total == sum(frame_bits(f["extended"], f["dlc"]) for f in frames)
        assert (counters.own_echoes > 0) == (rig.bus.__class__.__name__ == "UdpMulticastBus")
