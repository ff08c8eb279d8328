"""The real-time peer tells a rover in another process that its CAN controller is bus-off.

``run_peer`` runs here in-process on a virtual clock, with a ``CanLink`` on the rover's end of the bus
taking its turn every 20 ms between the peer's steps (as ``rover run`` would, in its own process), on
both buses the peer and the rover can share: the lockstep pair, and python-can ``udp_multicast``
(inside a private network namespace), which also echoes the peer's error frames back to the peer.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import can
import pytest

from firmware_bridge.can_bus import CanConfig, open_bus
from firmware_bridge.can_health import CAN_ERR_BUSOFF, CAN_ERR_RESTARTED
from firmware_bridge.can_link import CanLink, CanLinkState
from firmware_bridge.mavlink_transport import memory_pipe_pair
from firmware_bridge.vesc import VescCodec
from hil.bus_off import BUS_OFF_REPEAT_NS, BusOffAnnouncer
from hil.faults import Fault, FaultSchedule
from hil.lockstep_bus import lockstep_bus_pair
from logs.clock import NS_PER_S
from logs.reader import RecordedMetadata, read_entries
from logs.settings import parse_toml
from logs.sink import MemorySink
from navigator.config import RoverConfig, rover_config_from_table
from tests.hil.world_harness import run_peer_on_test_clock, scenario_with
from tests.system.realtime_rig import fresh_multicast_group, needs_netns

MS = 1_000_000
T0_NS = 1_000 * NS_PER_S  # a monotonic clock's epoch is arbitrary; not zero
ROVER_PERIOD_NS = 20 * MS
FAULT_START_S, FAULT_END_S = 1.0, 2.0
CAN_OFF = f'[[faults]]\ntarget = "can"\nkind = "off"\nstart_s = {FAULT_START_S}\nduration_s = 1.0\n'
LINK_EVENTS = ("can_bus_off", "can_recovering", "can_recovered")


@dataclass
class Rover:
    """The rover's side: a ``CanLink`` on its end of the bus, driving at 0.5 m/s every 20 ms once it is
    listening (``listen_from_ns``); before that, whatever reaches its end is lost, as to a process not
    started yet."""

    bus: can.BusABC
    link: CanLink
    sink: MemorySink
    listen_from_ns: int
    states: list[tuple[int, CanLinkState]] = field(default_factory=list)

    def turn(self, now_ns: int) -> None:
        if now_ns < self.listen_from_ns:
            while self.bus.recv(timeout=0) is not None:
                pass
            return
        self.link.poll()
        self.link.send_wheel_speeds([0.5] * 6)
        self.states.append((now_ns, self.link.state))

    def events(self) -> list[tuple[float, str, str]]:
        """(seconds from the peer's start, kind, detail) of the link's bus-state events."""
        return [
            ((ns - T0_NS) / NS_PER_S, m["kind"], m["detail"])
            for topic, ns, m in self.sink.records
            if topic == "safety/events" and m["kind"] in LINK_EVENTS
        ]

    def tx_between(self, start_s: float, end_s: float) -> int:
        lo, hi = T0_NS + round(start_s * NS_PER_S), T0_NS + round(end_s * NS_PER_S)
        return sum(
            1
            for topic, ns, m in self.sink.records
            if topic == "can/frames" and m["direction"] == "tx" and lo <= ns < hi
        )


class RoverTurnsClock:
    """Virtual time that moves only by the peer's waits; the rover takes its turn every 20 ms of it."""

    def __init__(self) -> None:
        self.t = T0_NS
        self.rover: Rover | None = None
        self._next_turn_ns = T0_NS

    def now_ns(self) -> int:
        return self.t

    def wait(self, seconds: float) -> None:
        self.t += round(seconds * NS_PER_S)
        if self.rover is not None and self.t >= self._next_turn_ns:
            self._next_turn_ns += ROVER_PERIOD_NS
            self.rover.turn(self.t)


@contextmanager
def lockstep_pair() -> Iterator[tuple[can.BusABC, can.BusABC]]:
    peer_end, rover_end = lockstep_bus_pair("peer-bus-off")
    try:
        yield peer_end, rover_end
    finally:
        peer_end.shutdown()
        rover_end.shutdown()


@contextmanager
def udp_multicast_pair() -> Iterator[tuple[can.BusABC, can.BusABC]]:
    config = CanConfig(interface="udp_multicast", channel=fresh_multicast_group())
    peer_end = open_bus(config)
    try:
        rover_end = open_bus(config)
    except BaseException:
        peer_end.shutdown()
        raise
    try:
        yield peer_end, rover_end
    finally:
        peer_end.shutdown()
        rover_end.shutdown()


# Opens the two ends of a bus: (the peer's, the rover's).
BusPair = Callable[[], AbstractContextManager[tuple[can.BusABC, can.BusABC]]]
BUS_PAIRS = [
    pytest.param(lockstep_pair, id="lockstep"),
    pytest.param(udp_multicast_pair, marks=needs_netns, id="udp_multicast"),
]


def run_rover_against_peer(
    pair: BusPair,
    tmp_path: Path,
    faults: str,
    listen_from_s: float = 0.0,
    seconds: float = 3.0,
    start_on_command: bool = False,
) -> Rover:
    config: RoverConfig = rover_config_from_table(parse_toml("", "<defaults>"))
    codec = VescCodec.for_profile(config.vesc)
    clock = RoverTurnsClock()
    sim_mavlink, _rover_mavlink = memory_pipe_pair()
    with pair() as (peer_end, rover_end):
        sink = MemorySink()
        link = CanLink(rover_end, codec, clock, sink, config=config.can)
        rover = Rover(rover_end, link, sink, T0_NS + round(listen_from_s * NS_PER_S))
        clock.rover = rover
        run_peer_on_test_clock(
            scenario_with(faults),
            config,
            tmp_path / "peer",
            clock,
            peer_end,
            sim_mavlink,
            duration_ns=round(seconds * NS_PER_S),
            start_on_command=start_on_command,
        )
    return rover


@pytest.mark.realtime
@pytest.mark.parametrize("pair", BUS_PAIRS)
def test_the_rovers_link_goes_bus_off_at_the_faults_start_and_recovers_at_its_end(
    pair: BusPair, tmp_path: Path
) -> None:
    rover = run_rover_against_peer(pair, tmp_path, CAN_OFF)
    events = rover.events()
    assert [kind for _t, kind, _detail in events] == list(LINK_EVENTS), events
    (off_s, _, off_detail), (back_s, _, back_detail), (recovered_s, _, _) = events
    # The error frames themselves did it, on the rover's first turn after the peer's step sent them.
    assert f"error frame 0x{CAN_ERR_BUSOFF:x}" in off_detail
    assert f"error frame 0x{CAN_ERR_RESTARTED:x}" in back_detail
    assert FAULT_START_S <= off_s <= FAULT_START_S + 0.04
    assert FAULT_END_S <= back_s <= FAULT_END_S + 0.04 and back_s <= recovered_s < FAULT_END_S + 0.2
    # BUSOFF, repeated every 100 ms while the fault lasts, then RESTARTED: each counted as a bus error.
    repeats = round((FAULT_END_S - FAULT_START_S) * NS_PER_S) // BUS_OFF_REPEAT_NS - 1
    assert rover.link.counters.bus_errors == 1 + repeats + 1
    # Its sends would still go out on this bus (and be dropped at the peer): the link withheld them itself.
    assert rover.tx_between(off_s, back_s) == 0
    assert rover.link.counters.withheld >= (back_s - off_s) / (ROVER_PERIOD_NS / NS_PER_S) - 1
    off = [t for t, state in rover.states if state is CanLinkState.BUS_OFF]
    assert (min(off) - T0_NS) / NS_PER_S == off_s and (max(off) - T0_NS) / NS_PER_S < back_s
    assert rover.states[-1][1] is CanLinkState.OK
    # The peer keeps count of what it announced, in its recording beside its timing.
    runtime = [
        e.data
        for e in read_entries(tmp_path / "peer" / "truth.mcap", messages=False)
        if isinstance(e, RecordedMetadata) and e.name == "runtime"
    ]
    assert json.loads(runtime[-1]["bus_off_json"]) == {
        "error_frames_sent": 1 + repeats + 1,
        "repeats": repeats,
        "send_errors": 0,
    }


@pytest.mark.parametrize("pair", BUS_PAIRS)
def test_a_rover_that_starts_listening_during_a_bus_off_active_from_the_start_hears_it(
    pair: BusPair, tmp_path: Path
) -> None:
    fault = '[[faults]]\ntarget = "can"\nkind = "off"\nstart_s = 0.0\nduration_s = 1.5\n'
    rover = run_rover_against_peer(pair, tmp_path, fault, listen_from_s=0.5, seconds=2.0)
    events = rover.events()
    assert [kind for _t, kind, _detail in events] == list(LINK_EVENTS), events
    # The peer's first BUSOFF went to nobody; a repeat told the rover within the repeat period.
    assert 0.5 <= events[0][0] <= 0.5 + (BUS_OFF_REPEAT_NS + ROVER_PERIOD_NS) / NS_PER_S
    assert 1.5 <= events[1][0] <= 1.54


def test_overlapping_and_back_to_back_faults_are_one_bus_off() -> None:
    s = NS_PER_S
    faults = (
        Fault("can", "off", start_ns=1 * s, end_ns=2 * s),
        Fault("can", "off", start_ns=3 * s // 2, end_ns=3 * s),  # overlaps the first
        Fault("can", "off", start_ns=3 * s, end_ns=4 * s),  # starts as the second ends
        Fault("can", "intermittent", start_ns=0, end_ns=5 * s),  # not a bus-off
    )
    peer_end, rover_end = lockstep_bus_pair("overlapping-bus-off")
    announcer = BusOffAnnouncer(peer_end, FaultSchedule(faults), repeat_ns=10 * s)
    heard: list[tuple[int, int]] = []
    try:
        for t in range(0, 5 * s, 10 * MS):
            announcer.poll(t)
            while (msg := rover_end.recv(timeout=0)) is not None:
                assert msg.is_error_frame
                heard.append((t, msg.arbitration_id))
    finally:
        peer_end.shutdown()
        rover_end.shutdown()
    assert heard == [(1 * s, CAN_ERR_BUSOFF), (4 * s, CAN_ERR_RESTARTED)]
    assert (announcer.sent, announcer.repeats, announcer.send_errors) == (2, 0, 0)


def test_a_peer_holding_its_scenario_announces_the_bus_off_from_the_rovers_first_command(
    tmp_path: Path,
) -> None:
    """``--start-on-command``: no error frame while the scenario is held, though the fault's start from
    the peer's (1 s) passes in the hold; the bus-off comes ``FAULT_START_S`` after the rover began
    commanding (its first turn from 1.5 s)."""
    listen_from_s = 1.5
    rover = run_rover_against_peer(
        lockstep_pair, tmp_path, CAN_OFF, listen_from_s=listen_from_s, seconds=4.5, start_on_command=True
    )
    events = rover.events()
    assert [kind for _t, kind, _detail in events] == list(LINK_EVENTS), events
    (off_s, _, _), (back_s, _, _), _recovered = events
    begun = listen_from_s + FAULT_START_S
    # The rover's first turn, the peer's step that heard it, the error frame's next turn: within 60 ms.
    assert begun <= off_s <= begun + 0.06
    assert back_s - off_s == pytest.approx(FAULT_END_S - FAULT_START_S, abs=0.03)
    repeats = round((FAULT_END_S - FAULT_START_S) * NS_PER_S) // BUS_OFF_REPEAT_NS - 1
    assert rover.link.counters.bus_errors == 1 + repeats + 1
    runtime = [
        e.data
        for e in read_entries(tmp_path / "peer" / "truth.mcap", messages=False)
        if isinstance(e, RecordedMetadata) and e.name == "runtime"
    ]
    # The peer sent none while it held the scenario (they would have been lost on a rover not listening).
    assert json.loads(runtime[-1]["bus_off_json"])["error_frames_sent"] == 1 + repeats + 1
