"""One lockstep HIL test per failsafe: it fires one tick past its threshold and not before, takes its action
(wheels at zero, or speed limited), and clears as docs/safety.md says."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator

import pytest

from logs.commands import RoverCommand
from tests.runtime.rig import (
    MSG_ATTITUDE,
    MSG_GPS_RAW_INT,
    MSG_HEARTBEAT,
    TICK_NS,
    FakeGroundStation,
    Rig,
    rig_config,
)


def assert_fired_in_window(fired_ns: int | None, reference_ns: int, threshold_s: float) -> None:
    """Fired on the first control tick strictly past ``reference + threshold``, not on the tick before."""
    assert fired_ns is not None, "the failsafe never fired"
    threshold_ns = round(threshold_s * 1e9)
    assert fired_ns - reference_ns > threshold_ns, "fired before its threshold"
    assert fired_ns - TICK_NS - reference_ns <= threshold_ns, "fired later than one tick past its threshold"


def assert_wheels_stopped(rig: Rig, t_ns: int) -> None:
    assert rig.commands_at(t_ns)["speed_mps"] == [0.0] * 6


def assert_driving_again(rig: Rig, within_s: float = 3.0) -> None:
    rig.run_until(lambda: rig.stack.safety_mode.value == "DRIVING", within_s, "back to DRIVING")
    rig.control_tick()
    assert any(abs(v) > 0.0 for v in rig.commands_at(rig.now_ns)["speed_mps"])


@pytest.fixture
def rig() -> Iterator[Rig]:
    made = Rig(rig_config())
    yield made
    made.close()


def test_loop_stall_fires_past_200ms_gap_and_clears_on_next_on_time_tick(rig: Rig) -> None:
    rig.drive()
    rig.control_enabled = False
    for _ in range(9):  # 9 skipped ticks: a 200 ms gap, at the threshold, not past it
        rig.control_tick()
    rig.control_enabled = True
    rig.control_tick()
    assert rig.first_event_ns("failsafe.loop_stall") is None
    rig.control_enabled = False
    for _ in range(10):  # a 220 ms gap
        rig.control_tick()
    rig.control_enabled = True
    stalled_tick = rig.control_tick()
    assert rig.first_event_ns("failsafe.loop_stall") == stalled_tick
    assert_wheels_stopped(rig, stalled_tick)
    next_tick = rig.control_tick()
    assert rig.first_event_ns("cleared.loop_stall") == next_tick
    assert rig.stack.safety_mode.value == "DRIVING"


def test_wheel_controller_silent(rig: Rig) -> None:
    rig.drive()
    rig.bus.silent_ids = {3}
    rig.run_for(0.4)
    fired = rig.first_event_ns("failsafe.wheel_silent")
    last_heard = rig.last_rx_ns(
        "can/frames", lambda m: m["direction"] == "rx" and m["id"] & 0xFF == 3, rig.now_ns
    )
    assert_fired_in_window(fired, last_heard, 0.25)
    assert fired is not None
    assert_wheels_stopped(rig, fired)
    assert rig.stack.safety_mode.value == "HOLD"
    # CAN id 3 is wheel index 2: the link's event and the supervisor's name that wheel the same way.
    same_wheel = "wheel 2 (left rear, CAN id 3)"
    link_detail = rig.events("can_controller_silent")[0][1]["detail"]
    assert link_detail.startswith(f"motor controller of {same_wheel} silent for "), link_detail
    detail = rig.events("failsafe.wheel_silent")[0][1]["detail"]
    assert detail == f"motor controller of {same_wheel} silent for more than 250 ms", detail
    rig.bus.silent_ids = set()
    assert_driving_again(rig)
    assert rig.first_event_ns("cleared.wheel_silent") is not None
    alive = rig.events("can_controller_alive")[0][1]["detail"]
    assert alive == f"motor controller of {same_wheel} reports again", alive


def test_can_bus_off_when_sends_keep_failing(rig: Rig) -> None:
    rig.drive()
    rig.bus.send_fails = True
    first_failed = rig.control_tick()
    rig.run_for(0.3)
    assert_fired_in_window(rig.first_event_ns("failsafe.can_bus_off"), first_failed, 0.1)
    assert rig.stack.safety_mode.value == "HOLD"
    rig.bus.send_fails = False
    assert_driving_again(rig)
    assert rig.first_event_ns("cleared.can_bus_off") is not None


def test_autopilot_heartbeat_lost(rig: Rig) -> None:
    rig.drive()
    rig.wire.dropped = {MSG_HEARTBEAT}
    rig.run_for(4.2)
    fired = rig.first_event_ns("failsafe.heartbeat_lost")
    last = rig.last_rx_ns(
        "mavlink/raw", lambda m: m["direction"] == "rx" and m["name"] == "HEARTBEAT", rig.now_ns
    )
    assert_fired_in_window(fired, last, 3.0)
    assert fired is not None
    assert_wheels_stopped(rig, fired)
    rig.wire.dropped = set()
    assert_driving_again(rig, within_s=1.5)
    assert rig.first_event_ns("cleared.heartbeat_lost") is not None


def test_gps_lost_beyond_budget() -> None:
    # A generous estimator health limit, so the GPS budget is what is tested (not the covariance growth).
    rig = Rig(rig_config(gps_budget_s=1.0, estimator_unhealthy_s=30.0))
    try:
        rig.drive()
        rig.wire.dropped = {MSG_GPS_RAW_INT}
        rig.run_for(1.4)
        fired = rig.first_event_ns("failsafe.gps_lost")
        last = rig.last_rx_ns(
            "mavlink/raw", lambda m: m["direction"] == "rx" and m["name"] == "GPS_RAW_INT", rig.now_ns
        )
        assert_fired_in_window(fired, last, 1.0)
        assert fired is not None
        assert_wheels_stopped(rig, fired)
        rig.wire.dropped = set()
        assert_driving_again(rig)
        assert rig.first_event_ns("cleared.gps_lost") is not None
    finally:
        rig.close()


def _attitude_received(rig: Rig, before_ns: int) -> int:
    """When the rover last read an ATTITUDE at or before ``before_ns``."""
    return rig.last_rx_ns(
        "mavlink/raw", lambda m: m["direction"] == "rx" and m["name"] == "ATTITUDE", before_ns
    )


def test_attitude_lost_when_the_ahrs_goes_quiet_while_driving(rig: Rig) -> None:
    rig.drive()
    rig.wire.dropped = {MSG_ATTITUDE}
    rig.run_for(1.3)
    fired = rig.first_event_ns("failsafe.attitude_lost")
    assert_fired_in_window(fired, _attitude_received(rig, rig.now_ns), 1.0)
    assert fired is not None
    assert_wheels_stopped(rig, fired)
    assert rig.stack.safety_mode.value == "HOLD"
    # Read and fired on the 20 ms control grid: the first tick past the limit is 1020 ms after the last one.
    detail = rig.events("failsafe.attitude_lost")[0][1]["detail"]
    assert detail == "no AHRS attitude with a finite roll and pitch for 1020 ms (limit 1000 ms)", detail
    rig.wire.dropped = set()
    assert_driving_again(rig, within_s=1.5)
    assert rig.first_event_ns("cleared.attitude_lost") is not None


@pytest.mark.parametrize("tilt", [math.nan, math.inf])
def test_attitude_lost_when_every_attitude_has_no_usable_roll(tilt: float) -> None:
    """ATTITUDE keeps arriving, each one refused (``_reject_tilt``): the last usable tilt must not stand
    for ever, or a rover tipping now would never be stopped by the tip-over check."""
    rig = Rig(rig_config())
    try:
        rig.drive()
        last_usable = _attitude_received(rig, rig.now_ns)
        rejected_before = rig.stack.attitude_rejected
        rig.roll_override = tilt  # every ATTITUDE from the next physics tick on
        rig.run_for(1.3)
        fired = rig.first_event_ns("failsafe.attitude_lost")
        assert_fired_in_window(fired, last_usable, 1.0)
        assert fired is not None
        # Not a quiet AHRS: its messages kept coming (10 Hz) and each was refused for its roll.
        assert _attitude_received(rig, fired) > last_usable
        assert rig.stack.attitude_rejected - rejected_before >= 10
        assert_wheels_stopped(rig, fired)
        assert rig.stack.safety_mode.value == "HOLD"
        rig.roll_override = None  # usable attitudes again
        assert_driving_again(rig, within_s=1.5)
        assert rig.first_event_ns("cleared.attitude_lost") is not None
        assert rig.first_event_ns("failsafe.tip_over") is None
    finally:
        rig.close()


def test_estimator_unhealthy_while_driving() -> None:
    # GPS gone for long (budget off) and a tight health limit: dead reckoning soon becomes "unhealthy".
    config = rig_config(gps_budget_s=0.0)
    estimator = dataclasses.replace(config.estimator, healthy_position_std_m=0.35)
    config = dataclasses.replace(config, estimator=estimator)
    rig = Rig(config)
    try:
        rig.drive()
        rig.wire.dropped = {MSG_GPS_RAW_INT}
        rig.run_until(
            lambda: rig.first_event_ns("failsafe.estimator_unhealthy") is not None, 30.0, "unhealthy"
        )
        fired = rig.first_event_ns("failsafe.estimator_unhealthy")
        assert fired is not None
        first_unhealthy = min(
            t for tp, t, m in rig.sink.records if tp == "estimator/pose" and not m["healthy"] and t > 2e9
        )
        assert_fired_in_window(fired, first_unhealthy, 0.5)
        assert_wheels_stopped(rig, fired)
        rig.wire.dropped = set()
        rig.run_until(
            lambda: rig.first_event_ns("cleared.estimator_unhealthy") is not None, 15.0, "healthy again"
        )
    finally:
        rig.close()


def test_ground_link_lost_when_configured() -> None:
    ground = FakeGroundStation()
    rig = Rig(rig_config(ground_link_timeout_s=1.0), commands=ground)
    try:
        rig.run_until(lambda: _with_contact(rig, ground), 10.0, "driving")
        last_contact = rig.now_ns
        rig.run_for(1.2)
        assert_fired_in_window(rig.first_event_ns("failsafe.ground_link_lost"), last_contact, 1.0)
        assert rig.stack.safety_mode.value == "HOLD"
        ground.last_contact_ns = rig.now_ns
        rig.control_tick()
        assert rig.first_event_ns("cleared.ground_link_lost") == rig.now_ns
    finally:
        rig.close()


def _with_contact(rig: Rig, ground: FakeGroundStation) -> bool:
    ground.last_contact_ns = rig.now_ns
    return rig.stack.safety_mode.value == "DRIVING" and rig.body.speed > 0.3


def test_stuck_when_commanded_but_not_moving_latches_until_new_goal(rig: Rig) -> None:
    rig.bus.drop_commands = True  # the controllers never hear us: the rover cannot move
    rig.run_until(lambda: rig.first_event_ns("failsafe.stuck") is not None, 10.0, "stuck")
    first_push = min(
        t for tp, t, m in rig.sink.records if tp == "wheels/command" and abs(m["body_speed_mps"]) >= 0.2
    )
    assert_fired_in_window(rig.first_event_ns("failsafe.stuck"), first_push, 2.0)
    # Commands that never arrive drive no motor: no current, so no wheel counts as stalled.
    assert rig.first_event_ns("failsafe.wheel_stalled") is None
    rig.bus.drop_commands = False
    rig.run_for(0.5)
    assert rig.stack.safety_mode.value == "HOLD"  # latched
    rig.stack.set_goal(17.0, 16.0)
    assert rig.first_event_ns("cleared.stuck") is not None
    assert_driving_again(rig, within_s=4.0)


def test_wheel_stalled_holds_then_retries_and_clears_once_the_wheel_turns(rig: Rig) -> None:
    rig.drive()
    rig.vescs.set_stuck(1, True)  # the left middle wheel seizes; its motor stalls at the current limit
    seized = rig.now_ns
    rig.run_until(lambda: rig.first_event_ns("failsafe.wheel_stalled") is not None, 3.0, "wheel_stalled")
    fired = rig.first_event_ns("failsafe.wheel_stalled")
    assert fired is not None
    # Counted from the command in force when the controller first reported the wheel stalled: the tick
    # before the first control tick that read such a status.
    first_stalled_status = min(
        t
        for tp, t, m in rig.sink.records
        if tp == "wheels/status"
        and t > seized
        and m["wheels"][1]["erpm"] == 0
        and m["wheels"][1]["motor_current_a"] >= 2.0
    )
    first_seen_tick = -(-first_stalled_status // TICK_NS) * TICK_NS
    assert_fired_in_window(fired, first_seen_tick - TICK_NS, 1.0)
    detail = rig.events("failsafe.wheel_stalled")[0][1]["detail"]
    assert detail.startswith("wheel 1 (left middle, CAN id 2) commanded") and "A for" in detail
    assert_wheels_stopped(rig, fired)
    assert rig.stack.safety_mode.value == "HOLD"
    # Held for 2 s (the motor cools), then tried again: still seized, so it stalls and fires once more.
    rig.run_until(lambda: rig.first_event_ns("cleared.wheel_stalled") is not None, 3.0, "the retry")
    cleared = rig.first_event_ns("cleared.wheel_stalled")
    assert_fired_in_window(cleared, fired, 2.0)
    rig.run_until(lambda: len(rig.events("failsafe.wheel_stalled")) == 2, 2.0, "the second stall")
    assert cleared is not None and 1.0 < (rig.events("failsafe.wheel_stalled")[1][0] - cleared) * 1e-9 < 1.2
    # Free again: the next retry drives on, and nothing fires any more.
    rig.vescs.set_stuck(1, False)
    rig.run_until(lambda: len(rig.events("cleared.wheel_stalled")) == 2, 3.0, "the second retry")
    assert_driving_again(rig)
    rig.run_for(2.0)
    assert len(rig.events("failsafe.wheel_stalled")) == 2
    assert rig.stack.safety_mode.value == "DRIVING"


def test_a_wheel_that_keeps_stalling_is_latched_on_its_third_stall(rig: Rig) -> None:
    """Retrying a seized wheel every 3 s forever would hide ``stuck`` (each hold's zero commands reset
    its timer): the third stall within 30 s latches, like ``stuck``, until a new goal or resume."""
    rig.drive()
    rig.vescs.set_stuck(1, True)
    rig.run_until(lambda: len(rig.events("failsafe.wheel_stalled")) == 3, 12.0, "three stalls")
    third = rig.events("failsafe.wheel_stalled")[2][1]["detail"]
    assert "stall 3 in 30000 ms: latched until a new goal or resume" in third
    assert "latched" not in rig.events("failsafe.wheel_stalled")[1][1]["detail"]
    rig.run_for(6.0)  # two hold times and more: no retry now
    assert len(rig.events("cleared.wheel_stalled")) == 2 and rig.stack.safety_mode.value == "HOLD"
    rig.vescs.set_stuck(1, False)
    rig.stack.set_goal(17.0, 16.0)  # the operator has looked: a new goal clears it
    assert len(rig.events("cleared.wheel_stalled")) == 3
    assert_driving_again(rig, within_s=4.0)


def test_tip_over_margin() -> None:
    config = rig_config()
    tip_roll = config.vehicle.tip_roll_rad
    threshold = math.radians(config.safety.tip_margin_deg)
    rig = Rig(config)
    try:
        rig.drive()
        # Margin just above the threshold: 1.5 deg, as the turn's lateral acceleration (speed x yaw rate,
        # up to 0.09 m/s^2 here) takes up to 0.5 deg of it.
        rig.roll_override = tip_roll - threshold - math.radians(1.5)
        rig.run_for(0.5)
        assert rig.first_event_ns("failsafe.tip_over") is None
        rig.roll_override = tip_roll - threshold + math.radians(0.5)  # just below
        rig.run_for(0.3)
        fired = rig.first_event_ns("failsafe.tip_over")
        attitude_in = rig.last_rx_ns(
            "mavlink/raw", lambda m: m["direction"] == "rx" and m["name"] == "ATTITUDE", fired or 0
        )
        assert fired is not None and 0 <= fired - attitude_in < TICK_NS  # the first tick that saw it
        assert_wheels_stopped(rig, fired)
        rig.roll_override = tip_roll - threshold - math.radians(1.0)  # inside the hysteresis: still held
        rig.run_for(0.3)
        assert rig.first_event_ns("cleared.tip_over") is None
        rig.roll_override = 0.0
        assert_driving_again(rig)
    finally:
        rig.close()


def test_geofence_breach_holds() -> None:
    notch = [
        (0.0, 0.0),
        (4.0, 0.0),
        (4.0, 6.0),
        (12.0, 6.0),
        (12.0, 0.0),
        (20.0, 0.0),
        (20.0, 20.0),
        (0.0, 20.0),
    ]
    rig = Rig(rig_config(fence=tuple(notch)), start=(3.0, 3.0), goal=(17.0, 3.0))
    try:
        rig.run_until(lambda: rig.first_event_ns("failsafe.geofence") is not None, 20.0, "geofence")
        fired = rig.first_event_ns("failsafe.geofence")
        before = [
            m["pose"]["position"]["x"]
            for tp, t, m in rig.sink.records
            if tp == "estimator/pose" and t < (fired or 0)
        ]
        assert before and before[-1] <= 4.0 + 1e-9  # the tick before was still inside
        assert_wheels_stopped(rig, fired or 0)
        rig.stack.set_goal(30.0, 3.0)  # a goal outside the fence is refused
        assert rig.first_event_ns("goal_rejected") is not None
    finally:
        rig.close()


def test_battery_low_limits_speed_and_critical_holds(rig: Rig) -> None:
    rig.drive()
    rig.voltage_override = 20.8  # below low (21 V), above critical (20 V)
    rig.run_for(2.4)
    fired = rig.first_event_ns("failsafe.battery_low")
    first_low = min(
        t
        for tp, t, m in rig.sink.records
        if tp == "wheels/status" and m["wheels"][0]["input_voltage_v"] < 21.0
    )
    # The tick that first sees the low reading starts the debounce; STATUS_5 arrives between ticks.
    first_seen = first_low + (-first_low) % TICK_NS
    assert_fired_in_window(fired, first_seen, 2.0)
    assert rig.stack.safety_mode.value == "DRIVING"
    states = [m for tp, t, m in rig.sink.records if tp == "navigator/state" and t > (fired or 0)]
    assert states and all(m["speed_limit_reason"] == "battery low" for m in states)
    assert all(m["target_speed_mps"] <= 0.5 * 1.0 + 1e-9 for m in states)
    rig.voltage_override = 19.5
    rig.run_for(2.4)
    assert rig.first_event_ns("failsafe.battery_critical") is not None
    assert rig.stack.safety_mode.value == "HOLD"
    rig.voltage_override = 20.2  # above critical but inside its 0.3 V hysteresis: still held
    rig.run_for(0.3)
    assert rig.stack.safety_mode.value == "HOLD"
    rig.voltage_override = None
    assert_driving_again(rig)
    assert rig.first_event_ns("cleared.battery_low") is not None


def test_estop_from_ground_latches_until_resume() -> None:
    ground = FakeGroundStation()
    rig = Rig(rig_config(), commands=ground)
    try:
        rig.drive()
        ground.queued.append(RoverCommand("estop", rig.now_ns))
        tick = rig.control_tick()
        assert rig.first_event_ns("failsafe.estop") == tick
        assert_wheels_stopped(rig, tick)
        rig.run_for(1.0)
        assert rig.stack.safety_mode.value == "ESTOP"
        ground.queued.append(RoverCommand("resume", rig.now_ns))
        rig.control_tick()
        assert rig.first_event_ns("cleared.estop") is not None
        assert_driving_again(rig)
    finally:
        rig.close()


def test_every_mode_change_is_an_event_with_its_cause(rig: Rig) -> None:
    rig.drive()
    rig.bus.silent_ids = {1}
    rig.run_for(0.5)
    details = [m["detail"] for _, m in rig.events("mode")]
    assert details[0].startswith("IDLE -> DRIVING")
    assert details[1].startswith("DRIVING -> HOLD: wheel_silent")


def test_estop_over_mavlink_latches_estop() -> None:
    from pymavlink.dialects.v20 import common as mavlink2

    rig = Rig(rig_config())
    try:
        rig.drive()
        ground_station = mavlink2.MAVLink(rig.wire, srcSystem=255, srcComponent=190)
        ground_station.command_long_send(
            1, 191, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0.0, 21196.0, 0.0, 0.0, 0.0, 0.0, 0.0
        )
        tick = rig.control_tick()
        assert rig.first_event_ns("failsafe.estop") == tick
        assert_wheels_stopped(rig, tick)
        assert rig.stack.safety_mode.value == "ESTOP"
    finally:
        rig.close()
