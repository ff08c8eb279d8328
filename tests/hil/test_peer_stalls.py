"""The real-time peer counts the simulated time it drops when a step comes late, and says so on ``log``."""

from __future__ import annotations

import json
from pathlib import Path

from firmware_bridge.vesc import VescCodec
from hil.lockstep import lockstep_wires
from hil.peer import MAX_SUBSTEPS, PHYSICS_DT_NS, RealtimePeer
from hil.peer_stalls import PeerStalls, parse_stall_message, stall_message
from hil.step_clock import StepClock
from hil.world import SimWorld
from logs.reader import read_messages
from logs.recorder import McapRecorder
from logs.settings import parse_toml
from logs.topics import LOG
from navigator.config import rover_config_from_table
from tests.hil.world_harness import scenario_with

MS = 1_000_000


def test_a_gap_within_the_cap_is_integrated_whole_and_a_longer_one_is_a_stall() -> None:
    stalls = PeerStalls(cap_ns=50 * MS)
    assert stalls.note(10 * MS) == 10 * MS and stalls.note(50 * MS) == 50 * MS
    assert (stalls.stalls, stalls.dropped_ns) == (0, 0)
    assert stalls.note(440 * MS) == 50 * MS
    assert stalls.note(60 * MS) == 50 * MS
    assert (stalls.stalls, stalls.dropped_ns, stalls.longest_gap_ns) == (2, 400 * MS, 440 * MS)
    assert stalls.summary() == {"stalls": 2, "dropped_sim_ms": 400.0, "longest_step_gap_ms": 440.0}


def test_the_stall_message_reads_back() -> None:
    assert parse_stall_message(stall_message(440 * MS, 390 * MS)) == (440.0, 390.0)
    assert parse_stall_message("VESC command timeout: 6 wheel(s) stopped") is None


def test_a_late_step_drops_simulated_time_and_the_peer_records_and_reports_it(tmp_path: Path) -> None:
    scenario = scenario_with("")
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    clock = StepClock(0)
    status = tmp_path / "status.json"
    with (
        lockstep_wires(config.can, clock=clock) as wires,
        McapRecorder(tmp_path / "truth.mcap") as recorder,
    ):
        codec = VescCodec.for_profile(config.vesc)
        world = SimWorld(
            scenario, config.vehicle, codec, clock, wires.sim_bus, wires.sim_mavlink, recorder, scenario.seed
        )
        peer = RealtimePeer(world, clock, recorder, status)
        due = 2_000 * MS  # start-up before the first step is not a stall
        for _ in range(3):
            peer.tick(due)
            due += PHYSICS_DT_NS
        due += 430 * MS  # the peer's process was not scheduled for 440 ms: the scheduler skipped 43 ticks
        peer.tick(due)
        peer.write_status()
    cap_ms = MAX_SUBSTEPS * PHYSICS_DT_NS / MS
    assert peer.simulated_ns == 3 * PHYSICS_DT_NS + MAX_SUBSTEPS * PHYSICS_DT_NS
    assert (peer.stalls.stalls, peer.stalls.dropped_ns) == (1, (440 - cap_ms) * MS)
    written = json.loads(status.read_text(encoding="utf-8"))
    assert (written["stalls"], written["dropped_sim_ms"], written["longest_step_gap_ms"]) == (
        1,
        440 - cap_ms,
        440.0,
    )
    logged = [m for m in read_messages(tmp_path / "truth.mcap", [LOG]) if m.message["name"] == "hil.peer"]
    assert [parse_stall_message(m.message["message"]) for m in logged] == [(440.0, 440 - cap_ms)]
    assert logged[0].log_time_ns == due == clock.now_ns()
