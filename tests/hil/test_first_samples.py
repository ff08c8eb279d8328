"""The simulated autopilot's first samples, stepped as ``SimWorld`` steps it: made at the world's epoch,
first stepped one 10 ms physics tick later. A stream at 50 Hz (the IMU; a GPS at ``gps_rate_hz = 50``)
used to send its first sample on that tick and its second 10 ms later, on its cadence from the epoch: the
rover's 50 Hz loop took both in its first read, and a `rover hil trial` recording had two first GPS fixes
(and two first IMU samples) at the same time. Stepping the autopilot from its own start, as a test of it
alone did, never showed it."""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from firmware_bridge.mavlink_link import GpsFix, ImuSample, MavlinkLink
from firmware_bridge.mavlink_transport import memory_pipe_pair
from hil.autopilot_sim import SimAutopilot
from hil.scenario import load_scenario, scenario_from_table
from hil.sensors import ImuModel
from hil.trial import run_trial
from logs import topics
from logs.clock import SimClock
from logs.reader import read_messages
from logs.settings import parse_toml
from logs.sink import MemorySink
from navigator.config import rover_config_from_table
from tests.hil.test_autopilot_sim import DATUM, TRUTH

TICK_NS = 10_000_000  # SimWorld's physics tick (hil.trial.PHYSICS_DT_NS)
MS = 1_000_000
DEFAULT = Path(__file__).resolve().parents[2] / "scenarios" / "default.toml"


def _sent_ms(*, first_step_ns: int, ticks: int, gps_rate_hz: float) -> dict[str, list[int]]:
    """When (ms on the clock) the autopilot's GPS fixes, IMU samples and heartbeats reach the rover's link,
    stepped every tick from ``first_step_ns`` after it was made."""
    clock, sink = SimClock(), MemorySink()
    companion_end, autopilot_end = memory_pipe_pair()
    link = MavlinkLink(companion_end, clock, sink)
    sim = SimAutopilot(
        autopilot_end, clock, np.random.default_rng(1), datum_lat_deg=DATUM[0], datum_lon_deg=DATUM[1],
        datum_alt_m=DATUM[2], gps_rate_hz=gps_rate_hz,
    )  # fmt: skip
    if first_step_ns:
        clock.advance(first_step_ns)
    sent: dict[str, list[int]] = {"gps": [], "imu": [], "heartbeat": []}
    for _ in range(ticks):
        heartbeats = sim.sent["heartbeat"]
        sim.step(TRUTH)
        for reading in link.poll():
            kind = "gps" if isinstance(reading, GpsFix) else "imu" if isinstance(reading, ImuSample) else ""
            if kind:
                sent[kind].append(clock.now_ns() // MS)
        if sim.sent["heartbeat"] > heartbeats:
            sent["heartbeat"].append(clock.now_ns() // MS)
        clock.advance(TICK_NS)
    return sent


def test_a_50_hz_stream_starts_on_its_cadence_when_the_first_step_is_a_tick_late() -> None:
    sent = _sent_ms(first_step_ns=TICK_NS, ticks=100, gps_rate_hz=50.0)
    assert sent["gps"][:4] == [20, 40, 60, 80]  # was [10, 20, 40, 60]: the first taken, not sent
    assert sent["imu"][:4] == [20, 40, 60, 80]
    assert len(sent["gps"]) == len(set(sent["gps"])) == 50


def test_the_first_sample_is_taken_though_not_sent(monkeypatch: pytest.MonkeyPatch) -> None:
    """Its noise drawn, as a lost GPS fix's is: every later sample's noise is what it was before."""
    taken: list[int] = []
    read = ImuModel.read

    def counted(self: ImuModel, now: int, *args: Any) -> Any:
        taken.append(now // MS)
        return read(self, now, *args)

    monkeypatch.setattr(ImuModel, "read", counted)
    sent = _sent_ms(first_step_ns=TICK_NS, ticks=6, gps_rate_hz=5.0)
    assert taken == [10, 20, 40, 60] and sent["imu"] == [20, 40, 60]


def test_slower_streams_still_start_at_the_first_step() -> None:
    # 10 ms late of 200 ms (a 5 Hz GPS) or of 1 s (the heartbeat a rover waits for before it starts).
    sent = _sent_ms(first_step_ns=TICK_NS, ticks=150, gps_rate_hz=5.0)
    assert sent["gps"][:3] == [10, 200, 400]
    assert sent["heartbeat"] == [10, 1000]


@pytest.mark.parametrize("first_step_ns", [0, 3_000 * MS])
def test_a_first_step_on_time_or_a_period_late_starts_every_stream_there(first_step_ns: int) -> None:
    # The autopilot stepped from its own start (tests of it alone), or after the real-time peer's warm-up.
    sent = _sent_ms(first_step_ns=first_step_ns, ticks=10, gps_rate_hz=50.0)
    start = first_step_ns // MS
    assert sent["gps"] == sent["imu"] == [start + 20 * k for k in range(5)]


def test_a_trial_at_gps_rate_50_records_one_fix_per_control_tick(tmp_path: Path) -> None:
    """The reproduction: the default scenario with ``[sensors] gps_rate_hz = 50``, a second of it."""
    text = DEFAULT.read_text(encoding="utf-8")
    assert "gps_rate_hz = 5.0" in text and "duration_s = 120.0" in text
    text = text.replace("gps_rate_hz = 5.0", "gps_rate_hz = 50.0").replace(
        "duration_s = 120.0", "duration_s = 1.0"
    )
    scenario = scenario_from_table(parse_toml(text, "gps50.toml"), text, DEFAULT.parent)
    assert scenario.sensors.gps_rate_hz == 50.0 and load_scenario(DEFAULT).sensors.gps_rate_hz == 5.0
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    result = run_trial(scenario, config, tmp_path)
    for topic in (topics.SENSORS_GPS, topics.SENSORS_IMU):
        times = [m.log_time_ns for m in read_messages(result.mcap_path, [topic])]
        repeated = [t for t, count in Counter(times).items() if count > 1]
        assert repeated == [], f"{topic}: several samples at {repeated} ns"
        assert times[:3] == [20 * MS, 40 * MS, 60 * MS], topic


def test_a_trial_records_each_motor_status_once_per_period_from_the_first(tmp_path: Path) -> None:
    """The simulated VESCs start their 50 Hz status as the autopilot does (``hil.first_sample``): each
    controller's first two fast statuses used to reach the rover's first poll together, at 20 ms."""
    text = DEFAULT.read_text(encoding="utf-8").replace("duration_s = 120.0", "duration_s = 1.0")
    scenario = scenario_from_table(parse_toml(text, "short.toml"), text, DEFAULT.parent)
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    result = run_trial(scenario, config, tmp_path)
    received = Counter(
        (m.message["id"], m.log_time_ns)
        for m in read_messages(result.mcap_path, [topics.CAN_FRAMES])
        if m.message["direction"] == "rx"
    )
    assert received, "no status frame was recorded"
    assert [key for key, count in received.items() if count > 1] == []
    fast_status = {ident for ident, _ in received if ident >> 8 == 0x09}  # VESC STATUS (command 9)
    assert len(fast_status) == 6
    for ident in fast_status:
        times = sorted(t for i, t in received if i == ident)
        assert times[:3] == [20 * MS, 40 * MS, 60 * MS], hex(ident)
