"""Every fault type shows in the recorded data, only while it is active, and is announced on ``log``."""

from __future__ import annotations

import dataclasses
import gc
import logging
import math

import numpy as np
import pytest

from firmware_bridge.can_health import CAN_ERR_BUSOFF
from hil.faults import Fault, FaultSchedule
from hil.trial import run_trial
from logs.reader import read_messages
from logs.settings import ConfigError, parse_toml
from logs.topics import SAFETY_EVENTS
from navigator.config import rover_config_from_table
from tests.hil.world_harness import WorldRun, run_world, scenario_with


def fault(target: str, kind: str, start: float = 1.0, duration: float = 2.0, **params: object) -> str:
    lines = [
        "[[faults]]",
        f'target = "{target}"',
        f'kind = "{kind}"',
        f"start_s = {start}",
        f"duration_s = {duration}",
    ]
    lines += [f"{key} = {value!r}".replace("(", "[").replace(")", "]") for key, value in params.items()]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def baseline() -> WorldRun:
    return run_world()


def announced(run: WorldRun, name: str) -> bool:
    messages = [m["message"] for m in run.on("log") if m["name"] == "hil.faults"]
    return any(f"fault injected: {name}" in m for m in messages) and any(
        f"cleared: {name}" in m for m in messages
    )


def test_gps_off_loses_fixes_only_in_the_window(baseline):
    run = run_world(fault("gps", "off"))
    assert run.on("sensors/gps", 1.0, 3.0) == []
    assert len(run.on("sensors/gps", 3.05, 4.0)) >= 3
    assert len(baseline.on("sensors/gps", 1.0, 3.0)) == 10
    assert announced(run, "gps/off")


def test_gps_glitch_offsets_the_fixes(baseline):
    run = run_world(fault("gps", "wrong", offset_m=(6.0, -4.0)))
    inside = np.array([(e, n) for _t, e, n in run.gps_enu(1.0, 3.0)])
    base = np.array([(e, n) for _t, e, n in baseline.gps_enu(1.0, 3.0)])
    assert inside.mean(axis=0) - base.mean(axis=0) == pytest.approx([6.0, -4.0], abs=0.05)
    after = np.array([(e, n) for _t, e, n in run.gps_enu(3.05, 4.0)])
    after_base = np.array([(e, n) for _t, e, n in baseline.gps_enu(3.05, 4.0)])
    assert np.allclose(after, after_base)


def test_gps_delay_reports_where_the_rover_was():
    run = run_world(
        fault("gps", "delayed", start=0.0, duration=10.0, delay_s=1.0) + "[sensors]\ngps_noise_m = 0.0\n"
    )
    truth = [(m, m["pose"]["position"]) for m in run.on("truth/pose")]
    fixes = run.gps_enu(2.5, 4.0)
    assert fixes
    for t_ns, e, n in fixes:
        earlier = min(truth, key=lambda item: abs(_ns(item[0]) - (t_ns - 1_000_000_000)))[1]
        now = min(truth, key=lambda item: abs(_ns(item[0]) - t_ns))[1]
        assert math.hypot(e - earlier["x"], n - earlier["y"]) < 0.05
        assert math.hypot(e - now["x"], n - now["y"]) > 0.3  # it moved ~0.6 m in that second


def _ns(message: dict) -> int:
    return message["timestamp"]["sec"] * 1_000_000_000 + message["timestamp"]["nsec"]


def test_gps_slow_and_intermittent_thin_the_fixes(baseline):
    slow = run_world(fault("gps", "slow", factor=5.0))
    assert len(slow.on("sensors/gps", 1.0, 3.0)) == 2  # 5 Hz / 5 for 2 s
    flaky = run_world(fault("gps", "intermittent", start=0.0, duration=10.0, probability=0.5))
    assert 4 <= len(flaky.on("sensors/gps")) <= 16  # of 20; binomial(20, 0.5) leaves this range rarely


def test_gps_garbage_reports_no_fix():
    run = run_world(fault("gps", "garbage"))
    inside = run.on("sensors/gps", 1.0, 3.0)
    assert inside and all(m["fix_type"] == 0 and m["satellites"] == 0 for m in inside)
    assert all(m["fix_type"] == 3 for m in run.on("sensors/gps", 3.05, 4.0))


def test_imu_bias_stuck_and_off(baseline):
    biased = run_world(fault("imu", "wrong", gyro_bias_rps=(0.0, 0.0, 0.2), accel_bias_mps2=(0.5, 0.0, 0.0)))
    z = [m["angular_velocity"]["z"] for m in biased.on("sensors/imu", 1.0, 3.0)]
    z0 = [m["angular_velocity"]["z"] for m in baseline.on("sensors/imu", 1.0, 3.0)]
    assert np.mean(z) - np.mean(z0) == pytest.approx(0.2, abs=0.01)
    stuck = run_world(fault("imu", "stuck"))
    readings = [
        (m["angular_velocity"]["z"], m["linear_acceleration"]["x"])
        for m in stuck.on("sensors/imu", 1.05, 3.0)
    ]
    assert len(readings) > 50 and len(set(readings)) == 1
    off = run_world(fault("imu", "off"))
    assert off.on("sensors/imu", 1.0, 3.0) == [] and off.on("sensors/imu", 3.05, 4.0)


def test_can_bus_off_drop_and_delay(baseline):
    bus_off = run_world(fault("can", "off"))
    # No frame from the wire; only the rover's controller's own report that it left the bus (the error
    # frame its link records, marked "error"), at its first read into the fault.
    reports = [(f["id"], f.get("error")) for f in bus_off.rx_frames(1.0, 3.0)]
    assert reports == [(CAN_ERR_BUSOFF, True)] and bus_off.rx_frames(3.1, 4.0)
    assert announced(bus_off, "can/off")
    dropping = run_world(fault("can", "intermittent", probability=0.5))
    kept, full = len(dropping.rx_frames(1.0, 3.0)), len(baseline.rx_frames(1.0, 3.0))
    assert 0.3 * full < kept < 0.7 * full
    delayed = run_world(fault("can", "delayed", delay_s=0.5))
    assert delayed.rx_frames(1.0, 1.5) == [] and delayed.rx_frames(1.5, 3.0)


def test_can_corruption_changes_payloads_only_in_the_window(baseline):
    run = run_world(fault("can", "garbage", probability=1.0))
    before = [f["data"] for f in run.rx_frames(0.0, 0.99)]
    assert before == [f["data"] for f in baseline.rx_frames(0.0, 0.99)]
    inside = [f["data"] for f in run.rx_frames(1.0, 3.0)]
    inside_base = [f["data"] for f in baseline.rx_frames(1.0, 3.0)]
    assert len(inside) == len(inside_base)
    assert sum(a != b for a, b in zip(inside, inside_base, strict=True)) == len(inside)


def test_controller_reboot_is_silent_then_starts_fresh():
    run = run_world(fault("vesc", "off", start=1.0, duration=1.0, controller=2))
    ids = run.world.vescs.profile.controller_ids
    silent = [f for f in run.rx_frames(1.0, 2.0) if f["id"] & 0xFF == ids[2]]
    others = [f for f in run.rx_frames(1.0, 2.0) if f["id"] & 0xFF == ids[1]]
    assert silent == [] and others
    assert run.world.vescs.reboots == 1
    # After the reboot its tachometer counts from zero again: smaller than its neighbour's.
    last = run.on("wheels/status")[-1]["wheels"]
    assert abs(last[2]["tachometer"]) < 0.8 * abs(last[1]["tachometer"])


def mean_current(run: WorldRun, wheel: int, start_s: float = 2.0, end_s: float = 3.0) -> float:
    """The motor current a wheel's controller reported, on average over the window (A)."""
    status = run.on("wheels/status", start_s, end_s)
    return sum(m["wheels"][wheel]["motor_current_a"] for m in status) / len(status)


def test_stuck_wheel_does_not_turn_and_its_motor_stalls_at_the_current_limit(baseline):
    run = run_world(fault("vesc", "stuck", controller=4))
    inside = run.on("wheels/status", 1.5, 3.0)
    assert inside and all(m["wheels"][4]["erpm"] == 0 for m in inside)
    assert all(m["wheels"][3]["erpm"] > 100 for m in inside)
    # Commanded forward against the lock: the controller drives the stall current (its 10 A limit), at
    # the duty that takes across the winding (I R / V: 10 A x 0.1 ohm / ~25 V), and the pack pays I^2 R.
    limit = run.world.body.motor_current_limit_a
    stalled = [m["wheels"][4] for m in inside]
    assert all(w["motor_current_a"] == pytest.approx(limit, abs=0.1) for w in stalled)
    assert all(0.02 < w["duty"] < 0.06 for w in stalled)
    assert all(w["input_current_a"] >= 0.3 for w in stalled[5:])  # STATUS_4 at 10 Hz: from its first one
    truth = run.on("truth/wheels", 1.5, 3.0)
    assert all(m["wheels"][4]["current_a"] == pytest.approx(limit) for m in truth)
    # It skids against the ground (mu N against the rover's motion): the other wheels of its side pull that
    # on top of the rolling resistance, so their controllers report several times the current they draw
    # without the fault, and more than the other side's; its moment turns the rover toward it (right).
    for wheel in (3, 5):
        assert mean_current(run, wheel) > 3.0 * mean_current(baseline, wheel)
        assert mean_current(run, wheel) > max(mean_current(run, other) for other in (0, 1, 2))
    heading, base_heading = (r.on("truth/pose", 2.95, 3.0)[-1]["yaw_rad"] for r in (run, baseline))
    assert heading < base_heading - 0.01
    # Free again after the fault: turning, at a driving current below the limit.
    after = run.on("wheels/status", 3.5, 4.0)
    assert after and all(m["wheels"][4]["erpm"] > 100 for m in after)
    assert all(abs(m["wheels"][4]["motor_current_a"]) < 0.9 * limit for m in after)


def test_mavlink_loss_and_garbage(baseline):
    lost = run_world(fault("mavlink", "off"))
    assert [m for m in lost.on("mavlink/raw", 1.0, 3.0) if m["direction"] == "rx"] == []
    assert [m for m in lost.on("mavlink/raw", 3.05, 4.0) if m["direction"] == "rx"]
    garbled = run_world(fault("mavlink", "garbage", probability=1.0))
    rx = [m for m in garbled.on("mavlink/raw", 1.05, 3.0) if m["direction"] == "rx"]
    rx_base = [m for m in baseline.on("mavlink/raw", 1.05, 3.0) if m["direction"] == "rx"]
    assert len(rx) < 0.8 * len(rx_base)  # corrupted frames fail their CRC and are not decoded
    # The link's own count of the garbage is recorded (mavlink/stats, once a second): none before the
    # fault or in the baseline, bad frames in every window of the fault.
    assert all(m["bad_frames"] == 0 for m in baseline.on("mavlink/stats"))
    assert all(m["bad_frames"] == 0 for m in garbled.on("mavlink/stats", 0.0, 1.0))
    during = garbled.on("mavlink/stats", 2.0, 3.05)  # the windows ending at 2 s and 3 s
    assert len(during) == 2 and all(m["bad_crc"] > 5 for m in during)
    assert during[-1]["bad_frames_total"] > during[0]["bad_frames_total"]


def test_battery_sag_lowers_the_reported_voltage(baseline):
    run = run_world(fault("battery", "wrong", sag_v=3.0, extra_resistance_ohm=0.2))
    volts = [m["battery_voltage_v"] for m in run.on("truth/wheels", 1.1, 3.0)]
    volts_base = [m["battery_voltage_v"] for m in baseline.on("truth/wheels", 1.1, 3.0)]
    assert np.mean(volts_base) - np.mean(volts) > 3.0
    status = [w["input_voltage_v"] for m in run.on("wheels/status", 1.5, 3.0) for w in m["wheels"]]
    assert max(status) < 22.5  # the controllers report the sagging pack (25.2 V when full)


def _speeds(run: WorldRun, start_s: float, end_s: float) -> list[float]:
    return [m["speed_mps"] for m in run.on("truth/pose", start_s, end_s)]


def test_battery_sag_slows_a_rover_at_top_speed_only_while_it_sags():
    """At 1.5 m/s the motors need ~20.1 V at the pack's terminals (back-EMF at duty 0.95, docs/physics.md).
    The 3 V sag above leaves ~21.7 V and changes nothing; a 6 V sag leaves ~18.6 V, where the wheels turn
    at most ~1.39 m/s: the rover slows in truth/pose and the VESCs report that speed at the top duty.
    2.4 s, as the drive from small_rocky's start reaches its rock at ~2.7 s at this speed."""
    base = run_world(seconds=2.4, speed_mps=1.5)
    window = {"start": 0.5, "duration": 1.0, "extra_resistance_ohm": 0.2}
    mild = run_world(fault("battery", "wrong", sag_v=3.0, **window), seconds=2.4, speed_mps=1.5)
    assert _speeds(mild, 0.0, 2.4) == _speeds(base, 0.0, 2.4)
    sagging = run_world(fault("battery", "wrong", sag_v=6.0, **window), seconds=2.4, speed_mps=1.5)
    assert _speeds(sagging, 0.0, 0.5) == _speeds(base, 0.0, 0.5)
    during, during_base = _speeds(sagging, 1.0, 1.5), _speeds(base, 1.0, 1.5)
    assert max(during) < 1.39 < 1.49 < min(during_base)
    wheels = [w for m in sagging.on("wheels/status", 1.0, 1.5) for w in m["wheels"]]
    assert max(w["speed_mps"] for w in wheels) < 1.395
    assert [w["duty"] for w in wheels] == pytest.approx([0.95] * len(wheels), abs=2e-3)
    assert _speeds(sagging, 2.0, 2.4) == pytest.approx(_speeds(base, 2.0, 2.4), abs=2e-3)  # it sped up again


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('target = "gps"\nkind = "stuck"', "faults[0].kind"),
        ('target = "laser"\nkind = "off"', "faults[0].target"),
        ('target = "gps"\nkind = "off"\nstart_s = 9999.0', "faults[0].start_s"),
        # small_rocky.toml lasts 45 s: a fault the trial cannot run in full is refused when loaded.
        ('target = "gps"\nkind = "off"\nstart_s = 45.0', "faults[0].start_s"),
        ('target = "gps"\nkind = "off"\nstart_s = 40.0\nduration_s = 6.0', "faults[0].duration_s"),
        ('target = "imu"\nkind = "off"\noffset_m = [1.0, 2.0]', "offset_m"),
        # A GPS gone to garbage reports nonsense on every fix: a probability would be silently ignored.
        ('target = "gps"\nkind = "garbage"\nprobability = 0.2', "faults[0].probability"),
    ],
)
def test_bad_faults_name_the_key(text, key):
    with pytest.raises(ConfigError) as caught:
        scenario_with("[[faults]]\n" + text + "\n")
    assert key in str(caught.value)


def test_a_trial_with_can_faults_shuts_its_fault_wrapper(tmp_path, caplog):
    # python-can logs "<class> was not properly shut down" (logger "can") when it collects a bus left open.
    faulty = scenario_with(fault("can", "off", start=0.5, duration=0.5))
    scenario = dataclasses.replace(faulty, duration_s=1.5)
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    with caplog.at_level(logging.WARNING, logger="can"):
        result = run_trial(scenario, config, tmp_path)
        gc.collect()
    assert result.simulated_s >= 1.0
    assert not [r.getMessage() for r in caplog.records if "not properly shut down" in r.getMessage()]


def test_can_bus_off_fires_the_rovers_can_bus_off_failsafe_in_a_lockstep_trial(tmp_path):
    # The rover's own controller goes bus-off (hil.bus_off), not only the wire: the link says so and the
    # supervisor holds the rover, then lets it drive on once the bus is back.
    scenario = scenario_with(fault("can", "off", start=8.0, duration=1.0))
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    result = run_trial(scenario, config, tmp_path)
    events = [
        (m.log_time_ns / 1e9, m.message["kind"]) for m in read_messages(result.mcap_path, [SAFETY_EVENTS])
    ]
    fired = [t for t, kind in events if kind == "failsafe.can_bus_off"]
    cleared = [t for t, kind in events if kind == "cleared.can_bus_off"]
    assert fired and 8.0 <= fired[0] < 8.02, events  # on the first control tick of the fault
    assert len(fired) == 1 and cleared and 9.0 <= cleared[0] < 9.1
    sent = [
        m.log_time_ns / 1e9
        for m in read_messages(result.mcap_path, ["can/frames"])
        if m.message["direction"] == "tx" and 8.0 <= m.log_time_ns / 1e9 < 9.0
    ]
    assert sent == []
    assert result.end_reason == "arrived", result.failures


def test_the_next_change_is_the_first_start_or_end_after_now_on_the_schedules_clock():
    """The world redoes the faults' effects only from the tick at or past this moment (hil.world)."""
    second = 1_000_000_000
    schedule = FaultSchedule(
        (Fault("vesc", "off", 2 * second, 5 * second), Fault("battery", "wrong", 3 * second, 4 * second)),
        epoch_ns=7 * second,
    )
    assert schedule.next_change_ns(7 * second) == 9 * second  # world time 0: the first start, at 2 s
    assert schedule.next_change_ns(9 * second) == 10 * second  # at a start: the next one, not itself
    assert schedule.next_change_ns(10 * second + 1) == 11 * second
    assert schedule.next_change_ns(11 * second) == 12 * second
    assert schedule.next_change_ns(12 * second) == math.inf
