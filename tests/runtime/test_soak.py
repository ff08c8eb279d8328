"""The soak: its seeded plan, and a 32 s real-time soak (peer + rover run, four faults) judged clean."""

from __future__ import annotations

import itertools
import json
import math
import subprocess
from pathlib import Path
from typing import cast

import pytest

from hil.hardware_priority import PEER_FIFO_PRIORITY
from hil.scenario import load_scenario
from hil.soak import SoakSettings, SoakSetupError, _wait_for_scenario_start, run_soak
from hil.soak_plan import CATALOG, fault_plan, scenario_text
from tests.system.realtime_rig import needs_netns


def test_the_plan_is_seeded_covers_every_fault_before_repeating_and_leaves_recovery_gaps() -> None:
    plan = fault_plan(11, 600.0, 20.0, (12.0, 20.0))
    assert plan == fault_plan(11, 600.0, 20.0, (12.0, 20.0)) and plan != fault_plan(
        12, 600.0, 20.0, (12.0, 20.0)
    )
    kinds = [(f.target, f.kind) for f in plan]
    assert set(kinds[: len(CATALOG)]) == {(target, kind) for target, kind, *_ in CATALOG}
    assert plan[0].start_s == 20.0 and plan[-1].end_s + 12.0 <= 600.0
    assert all(b.start_s - a.end_s >= 12.0 for a, b in itertools.pairwise(plan))


def test_the_scenario_carries_the_peer_side_faults(tmp_path: Path) -> None:
    plan = fault_plan(3, 60.0, 5.0, (3.0, 4.0))
    path = tmp_path / "soak.toml"
    path.write_text(scenario_text("soak", 60.0, 3, plan))
    scenario = load_scenario(path)
    peer_side = [f for f in plan if f.target != "estop"]
    assert [(f.target, f.kind) for f in scenario.faults] == [(f.target, f.kind) for f in peer_side]
    assert [f.start_ns for f in scenario.faults] == [round(f.start_s * 1e9) for f in peer_side]


class _Process:
    """A child process as the soak watches it: ``poll()`` is None while it runs."""

    def __init__(self, returncode: int | None = None) -> None:
        self.returncode = returncode

    def poll(self) -> int | None:
        return self.returncode


def _wait(status: Path, peer: _Process, rover: _Process) -> float:
    as_child = cast(subprocess.Popen[bytes], peer), cast(subprocess.Popen[bytes], rover)
    return _wait_for_scenario_start(status, *as_child)


def test_the_soaks_time_zero_is_when_the_peer_says_its_scenario_started(tmp_path: Path) -> None:
    status = tmp_path / "status.json"
    status.write_text(json.dumps({"x_m": 4.0, "scenario_started_ns": 1_234_500_000_000}))
    assert _wait(status, _Process(), _Process()) == 1_234.5


@pytest.mark.parametrize(("peer", "rover", "who"), [(None, 1, "rover run"), (1, None, "the HIL peer")])
def test_a_process_that_exits_before_the_rovers_first_command_stops_the_soak(
    tmp_path: Path, peer: int | None, rover: int | None, who: str
) -> None:
    status = tmp_path / "status.json"
    status.write_text(json.dumps({"scenario_started_ns": None, "scenario_held_s": 3.0}))  # still held
    with pytest.raises(SoakSetupError, match=f"^{who} exited \\(1\\) before the rover's first wheel command"):
        _wait(status, _Process(peer), _Process(rover))


def test_an_out_holding_an_earlier_soaks_recordings_is_refused_before_anything_runs(tmp_path: Path) -> None:
    (tmp_path / "peer").mkdir()
    (tmp_path / "peer" / "truth.mcap").write_bytes(b"an earlier soak's truth")
    with pytest.raises(SoakSetupError, match="holds an earlier soak's recordings"):
        run_soak(SoakSettings(seconds=60.0, seed=1, out_dir=tmp_path, can_interface="virtual"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["peer"]  # nothing written: no scenario, no logs
    assert (tmp_path / "peer" / "truth.mcap").read_bytes() == b"an earlier soak's truth"


@pytest.mark.realtime
@needs_netns
def test_a_short_soak_injects_sees_and_recovers_every_fault(tmp_path: Path) -> None:
    # Seed 3 in 32 s: a controller reboot, an e-stop over Zenoh, a silent IMU (the pacing sensor), a CAN
    # bus-off (the peer's error frames put the rover's link bus-off: hil.bus_off.BusOffAnnouncer).
    # The faults count from the rover's first wheel command (the peer holds its scenario until then:
    # `rover hil peer --start-on-command`), not from the peer's start: on this 2-core host `rover run`
    # first ticked 5-25 s after the peer under load, and a warm-up counted from the peer lost faults
    # before the rover ran. The 10 s warm-up is the rover's own start-up: estimate settled, driving.
    settings = SoakSettings(
        32.0, 3, tmp_path, rss_period_s=1.0, warmup_s=10.0, gap_s=(3.0, 4.0), peer_fifo=PEER_FIFO_PRIORITY
    )
    report = run_soak(settings)
    names = [f.name.split("[")[0] for f in report.faults]
    assert names == ["vesc", "estop/command", "imu/off", "can/off"], report.faults
    assert report.ok, report.to_json()
    (can_off,) = [f for f in report.faults if f.name == "can/off"]
    assert can_off.seen and "failsafe.can_bus_off" in can_off.evidence, can_off
    # Sensor-paced in part: the silent IMU's 3 s (~150 ticks) run on the deadline, and so does every tick
    # whose sample comes later than the grace. On this 2-core machine that share is the host's load:
    # 0.68-0.87 sensor-paced under the other helpers' load (load ~9; 0.51 once), 0.15-0.33 with two busy
    # loops besides. The judge holds the rover to its own pace around the silent IMU (hil.soak_report);
    # this floor fails a rover whose pacing is broken, not a busy host.
    assert not report.crashes and report.sensor_ticks > 0.2 * report.ticks
    # 50 Hz from the loop's first tick to the stop (0.85-1.0 of it seen, at load 12-14 too): a count
    # from the soak's start would measure how long this host took to start `rover run`.
    # The soak's time zero is the rover's first command, which its first tick sent: the report's estimate
    # of that tick (its first timing window less its ticks at 50 Hz) is close to it, however long the
    # rover took to come up.
    assert report.rover_first_tick_s is not None and abs(report.rover_first_tick_s) < 2.0, report
    assert report.ticks > 0.75 * 50.0 * (settings.seconds - report.rover_first_tick_s), report.ticks
    assert report.deadline_ticks > 0  # the silent IMU's fallback ticks
    # A normal start does not trip the stall failsafe (the first plan runs off the control thread).
    assert "failsafe.loop_stall" not in report.failsafe_events
    assert all(math.isfinite(m.max_mb) for m in report.memory)
    # The peer stopped cleanly and wrote its own timing; OK above means no stall beyond the bound.
    assert report.peer.overruns is not None and report.peer.longest_step_gap_ms is not None
    assert (tmp_path / "soak.json").exists()
    # The peer ran as timer-driven hardware where this machine allows, and the report says which.
    assert report.peer_scheduling.startswith(
        ("SCHED_FIFO 10, as timer-driven hardware", "normal scheduling (SCHED_FIFO 10 refused")
    )
