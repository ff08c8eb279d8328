"""Run the simulated world against the rover's own CAN and MAVLink links, recording into memory.

The rover side is the real ``CanLink`` and ``MavlinkLink`` (what the onboard stack records), driven with
constant wheel speeds, so a test sees faults the way a recording shows them.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import can
import pymap3d

from firmware_bridge.can_link import CanLink
from firmware_bridge.mavlink_link import MavlinkLink
from firmware_bridge.mavlink_transport import Transport
from firmware_bridge.vesc import VescCodec
from hil.lockstep import lockstep_wires
from hil.peer import PeerResult, run_peer
from hil.scenario import Scenario, scenario_from_table
from hil.world import SimWorld
from logs.clock import SimClock, to_ns
from logs.settings import parse_toml
from logs.sink import MemorySink
from logs.topics import stamp_ns
from navigator.config import RoverConfig, rover_config_from_table

DATA = Path(__file__).resolve().parents[1] / "data"
BASE = (DATA / "small_rocky.toml").read_text(encoding="utf-8")
DT_NS = 10_000_000


def scenario_with(extra: str, *, duration_s: float | None = None) -> Scenario:
    """small_rocky.toml with ``extra`` appended (and its 45 s ``duration_s`` replaced, when given)."""
    base = (
        BASE if duration_s is None else BASE.replace("duration_s = 45.0", f"duration_s = {duration_s!r}", 1)
    )
    text = base + "\n" + extra
    return scenario_from_table(parse_toml(text, "<test scenario>"), text, DATA)


@dataclass
class WorldRun:
    sink: MemorySink
    world: SimWorld
    scenario: Scenario

    def on(self, topic: str, start_s: float = 0.0, end_s: float = 1e9) -> list[dict]:
        lo, hi = to_ns(start_s), to_ns(end_s)
        return [m for t, ns, m in self.sink.records if t == topic and lo <= ns < hi]

    def rx_frames(self, start_s: float = 0.0, end_s: float = 1e9) -> list[dict]:
        return [f for f in self.on("can/frames", start_s, end_s) if f["direction"] == "rx"]

    def gps_enu(self, start_s: float = 0.0, end_s: float = 1e9) -> list[tuple[int, float, float]]:
        lat0, lon0, alt0 = self.scenario.datum
        out = []
        for fix in self.on("sensors/gps", start_s, end_s):
            e, n, _u = pymap3d.geodetic2enu(
                fix["latitude"], fix["longitude"], fix["altitude"], lat0, lon0, alt0
            )
            out.append((stamp_ns(fix["timestamp"]), float(e), float(n)))
        return out


def run_world(extra: str = "", seconds: float = 4.0, speed_mps: float = 0.6) -> WorldRun:
    scenario = scenario_with(extra)
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    clock, sink = SimClock(), MemorySink()
    with lockstep_wires(config.can, clock=clock) as wires:
        codec = VescCodec.for_profile(config.vesc)
        with SimWorld(
            scenario, config.vehicle, codec, clock, wires.sim_bus, wires.sim_mavlink, sink, scenario.seed
        ) as world:
            can_link = CanLink(world.rover_can_end(wires.onboard_bus), codec, clock, sink)
            mavlink = MavlinkLink(wires.onboard_mavlink, clock, sink)
            tick = 0
            while clock.now_ns() < to_ns(seconds):
                clock.advance(DT_NS)
                tick += 1
                world.tick(DT_NS / 1e9)
                if tick % 2 == 0:
                    can_link.poll()
                    mavlink.poll()
                    can_link.send_wheel_speeds([speed_mps] * 6)
        can_link.close()
    return WorldRun(sink, world, scenario)


class SteppedClock(Protocol):
    """A test clock the peer's waits advance (no real sleeping)."""

    def now_ns(self) -> int: ...

    def wait(self, seconds: float) -> None: ...


class StepClock:
    """The plainest ``SteppedClock``: 1000 s at the start, each wait moves it on by what was asked."""

    def __init__(self) -> None:
        self.t = 1_000_000_000_000

    def now_ns(self) -> int:
        return self.t

    def wait(self, seconds: float) -> None:
        self.t += round(seconds * 1e9)


def run_peer_on_test_clock(
    scenario: Scenario,
    config: RoverConfig,
    out_dir: Path,
    clock: SteppedClock,
    can_bus: can.BusABC,
    mavlink: Transport,
    *,
    duration_ns: int,
    status_path: Path | None = None,
    start_on_command: bool = False,
    start_timeout_ns: int | None = None,
) -> PeerResult:
    """``hil.peer.run_peer`` on in-process wires for ``duration_ns``: its waits advance ``clock``, nothing
    is spun or slept, never stopped from outside."""
    return run_peer(
        scenario,
        config,
        out_dir,
        clock=clock,
        can_bus=can_bus,
        mavlink=mavlink,
        mavlink_port=14_550,
        wait=clock.wait,
        stop=threading.Event(),
        duration_ns=duration_ns,
        status_path=status_path,
        spin_ns=0,
        start_on_command=start_on_command,
        start_timeout_ns=start_timeout_ns,
    )
