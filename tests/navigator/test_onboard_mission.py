"""Missions in the onboard stack: uploaded by a ground station over MAVLink, driven waypoint by waypoint on
the lockstep rig (the real stack against the simulated rover), replaced by a single goal, resumed, cleared,
refused whole when a waypoint is outside the geofence or the rover has no datum yet; an upload waits for
MISSION_START unless it replaces a mission being driven."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from estimator.geodesy import Datum, to_geodetic
from firmware_bridge.mavlink_transport import memory_pipe_pair
from navigator.mission import MissionState
from navigator.route_guidance import Mode
from navigator.safety import WHEEL_STALLED
from tests.firmware_bridge.ground_station import (
    MISSION,
    ROVER,
    GroundStation,
    change_speed,
    mission_start,
    waypoint,
)
from tests.runtime.rig import DATUM, MSG_GPS_RAW_INT, Rig, rig_config

# ENU metres on the rig's open 20 m x 20 m map; the rover starts at (3, 3).
PLAN = [(6.0, 4.0), (7.0, 8.0), (4.0, 9.0)]


def plan_items(plan: list[tuple[float, float]] = PLAN) -> list[Any]:
    datum = Datum(*DATUM)
    return [waypoint(seq, *to_geodetic(datum, x, y, 0.0)[:2]) for seq, (x, y) in enumerate(plan)]


def flat(points: Any) -> list[float]:
    """Each point's x and y, one list (a waypoint's hold time left out)."""
    return [float(c) for point in points for c in point[:2]]


def points(details: list[str]) -> list[float]:
    """The (x, y) each event detail names, flattened."""
    return flat(tuple(map(float, d.split("(")[1].split(")")[0].split(", "))) for d in details)


class Station:
    """The rig with a ground station on its second MAVLink link."""

    def __init__(self, **rig: Any) -> None:
        rover_end, station_end = memory_pipe_pair()
        rig.setdefault("goal", (3.0, 3.0))  # the rig's own goal: where it stands (no drive of its own)
        self.rig = Rig(rig.pop("config", None) or rig_config(), ground_station=rover_end, **rig)
        self.gcs = GroundStation(station_end)

    def upload(self, plan: list[Any]) -> Any:
        """Upload ``plan`` a round trip per control tick; the rover's MISSION_ACK."""
        self.gcs.send(mavlink2.MAVLink_mission_count_message(*ROVER, len(plan), MISSION))
        for _ in range(len(plan) + 3):
            self.rig.control_tick()
            received = self.gcs.receive()
            acks = [m for m in received if m.get_type() == "MISSION_ACK"]
            if acks:
                return acks[0]
            self.gcs.answer(plan, received)
        raise AssertionError(f"no MISSION_ACK: {[m.get_type() for m in self.gcs.heard]}")

    def send(self, msg: Any) -> list[Any]:
        self.gcs.send(msg)
        self.rig.control_tick()
        return self.gcs.receive()

    def start(self, first: int = 0) -> None:
        """MAV_CMD_MISSION_START from item ``first``: acknowledged ACCEPTED."""
        (ack,) = [m for m in self.send(mission_start(first, 0)) if m.get_type() == "COMMAND_ACK"]
        assert ack.result == mavlink2.MAV_RESULT_ACCEPTED

    def details(self, kind: str) -> list[str]:
        return [m["detail"] for _, m in self.rig.events(kind)]

    def close(self) -> None:
        self.rig.close()


@pytest.fixture
def station() -> Any:
    made = Station()
    yield made
    made.close()


def test_an_uploaded_mission_is_driven_waypoint_by_waypoint_to_the_end(station: Station) -> None:
    rig = station.rig
    assert station.upload(plan_items()).type == mavlink2.MAV_MISSION_ACCEPTED
    assert station.details("mission")[-1].startswith(
        "mission of 3 waypoints from MAVLink upload by 255/190 on the ground_station link: (6.00, 4.00)"
    )
    mission = rig.stack.mission
    assert mission.state is MissionState.NOT_STARTED
    station.start()
    assert station.details("mission_started") == ["mission started at item 0 of 3 by 255/190"]
    rig.run_until(lambda: mission.state is MissionState.COMPLETE, 60.0, "the mission's end")
    assert rig.stack.mode is Mode.ARRIVED
    rig.control_tick()  # its navigator/state: the arrival's said ACTIVE, the mission advanced after it
    reached = station.details("mission_item_reached")
    assert [line.split(" (")[0] for line in reached] == ["item 0 of 3", "item 1 of 3", "item 2 of 3"]
    assert points(reached) == pytest.approx(flat(PLAN), abs=0.02)  # degrees x 1e7: ~1 cm
    # Each waypoint was guidance's goal in turn, in order, after the rig's own goal.
    assert points(station.details("goal")[-3:]) == pytest.approx(flat(PLAN), abs=0.02)
    assert math.hypot(rig.body.x - PLAN[-1][0], rig.body.y - PLAN[-1][1]) < 0.6
    # navigator/state said which item the goal was.
    seen = [m.get("mission") for topic, _, m in rig.sink.records if topic == "navigator/state"]
    currents = [s["current"] for s in seen if s is not None and s["state"] == "ACTIVE"]
    assert sorted(set(currents)) == [0, 1, 2] and currents == sorted(currents)
    assert seen[-1] == {"state": "COMPLETE", "current": 2, "count": 3}
    # The ground station was told: each item reached, and the progress.
    station.gcs.receive()
    assert [m.seq for m in station.gcs.of_type("MISSION_ITEM_REACHED")] == [0, 1, 2]
    last = station.gcs.of_type("MISSION_CURRENT")[-1]
    assert (last.seq, last.total, last.mission_state) == (3, 3, mavlink2.MISSION_STATE_COMPLETE)


def test_a_waypoint_with_a_hold_time_keeps_the_rover_there_that_long_then_goes_on(station: Station) -> None:
    rig = station.rig
    items = plan_items(PLAN[:2])
    items[0].param1 = 2.0  # hold 2 s at the first waypoint (ArduPilot Rover's delay, PX4's hold time)
    assert station.upload(items).type == mavlink2.MAV_MISSION_ACCEPTED
    assert ": (6.00, 4.00) hold 2 s, (7.00, 8.00); not started" in station.details("mission")[-1]
    mission = rig.stack.mission
    station.start()
    arrived = rig.run_until(lambda: bool(station.details("mission_hold")), 30.0, "the hold at item 0")
    assert station.details("mission_hold") == ["item 0 of 2: holding 2 s"]
    station.gcs.receive()
    assert [m.seq for m in station.gcs.of_type("MISSION_ITEM_REACHED")] == [0]  # said on arrival
    went_on = rig.run_until(lambda: mission.current == 1, 5.0, "the mission going on")
    assert went_on - arrived >= 2_000_000_000 and went_on - arrived <= 2_000_000_000 + 40_000_000
    # The rover waited at the waypoint: ARRIVED, the wheels stopped, item 0 current on navigator/state.
    waiting = [
        m
        for topic, t, m in rig.sink.records
        if topic == "navigator/state" and arrived + 500_000_000 < t < went_on
    ]
    assert waiting and all(m["mode"] == "ARRIVED" and m["mission"]["current"] == 0 for m in waiting)
    assert all(m["target_speed_mps"] == 0.0 for m in waiting)
    rig.run_until(lambda: mission.state is MissionState.COMPLETE, 30.0, "the mission's end")


def test_a_single_goal_during_a_hold_ends_it(station: Station) -> None:
    rig = station.rig
    items = plan_items(PLAN[:2])
    items[0].param1 = 30.0
    station.upload(items)
    station.start()
    rig.run_until(lambda: bool(station.details("mission_hold")), 30.0, "the hold at item 0")
    rig.stack.set_goal(2.0, 2.0)
    assert rig.stack.mission.state is MissionState.PAUSED
    set_current(station, 1)  # resumed further on: no hold left over from item 0 (30 s of it)
    rig.run_until(lambda: rig.stack.mission.state is MissionState.COMPLETE, 15.0, "the mission's end")
    assert [line.split(" (")[0] for line in station.details("mission_item_reached")] == [
        "item 0 of 2",
        "item 1 of 2",
    ]


def test_a_hold_at_the_last_waypoint_reports_it_current_then_completes(station: Station) -> None:
    rig = station.rig
    (item,) = plan_items(PLAN[:1])
    item.param1 = 1.5
    station.upload([item])
    station.start()
    arrived = rig.run_until(lambda: bool(station.details("mission_hold")), 30.0, "the hold")
    rig.run_for(1.2)  # MISSION_CURRENT once a second: the held item, the mission still ACTIVE
    station.gcs.receive()
    current = station.gcs.of_type("MISSION_CURRENT")[-1]
    assert (current.seq, current.mission_state) == (0, mavlink2.MISSION_STATE_ACTIVE)
    done = rig.run_until(lambda: rig.stack.mission.state is MissionState.COMPLETE, 2.0, "the end")
    assert 1_500_000_000 <= done - arrived <= 1_540_000_000


def test_a_mission_cleared_or_replaced_during_a_hold_leaves_no_wait_behind(station: Station) -> None:
    rig = station.rig
    first, second = plan_items(PLAN[:2])
    first.param1 = 30.0
    station.upload([first, second])
    station.start()
    rig.run_until(lambda: bool(station.details("mission_hold")), 30.0, "the hold at item 0")
    station.send(mavlink2.MAVLink_mission_clear_all_message(*ROVER, MISSION))
    rig.run_for(0.1)
    # A new mission whose item 0 is where the rover stands, without a hold: done at once, not 30 s on.
    (here,) = plan_items([PLAN[0]])
    station.upload([here, plan_items(PLAN[:2])[1]])
    station.start()
    rig.run_until(lambda: rig.stack.mission.state is MissionState.COMPLETE, 15.0, "the new mission's end")


def test_a_waypoint_outside_the_geofence_refuses_the_upload_and_keeps_the_mission() -> None:
    fence = ((1.0, 1.0), (10.0, 1.0), (10.0, 10.0), (1.0, 10.0))
    station = Station(config=rig_config(fence=fence))
    try:
        assert station.upload(plan_items()).type == mavlink2.MAV_MISSION_ACCEPTED
        station.start()
        outside = [PLAN[0], (15.0, 5.0), PLAN[2]]
        answer = station.upload(plan_items(outside))
        assert answer.type == mavlink2.MAV_MISSION_DENIED
        text = "".join(m.text for m in station.gcs.of_type("STATUSTEXT"))
        assert "item 1: waypoint (15.00, 5.00) is outside the geofence" in text
        mission = station.rig.stack.mission
        assert flat(mission.waypoints) == pytest.approx(flat(PLAN), abs=0.02)
        assert len(station.details("mission")) == 1 and mission.state is MissionState.ACTIVE
        # The trial runner's way in is refused the same way, whole.
        assert not station.rig.stack.start_mission(outside, "test")
        assert station.details("mission_rejected") == [
            "mission from test: waypoint 1 (15.00, 5.00) is outside the geofence"
        ]
    finally:
        station.close()


def _station_without_datum() -> Station:
    """A rover with no configured datum whose GPS fixes are all dropped: it never has a datum."""
    config = rig_config()
    config = dataclasses.replace(
        config,
        estimator=dataclasses.replace(
            config.estimator, datum_lat_deg=None, datum_lon_deg=None, datum_alt_m=None
        ),
    )
    station = Station(config=config)
    station.rig.wire.dropped.add(MSG_GPS_RAW_INT)  # no fix: no datum
    return station


def test_an_upload_before_the_rover_knows_its_datum_is_refused() -> None:
    station = _station_without_datum()
    try:
        assert station.upload(plan_items()).type == mavlink2.MAV_MISSION_DENIED
        text = "".join(m.text for m in station.gcs.of_type("STATUSTEXT"))
        assert "item 0: no ENU datum yet (no GPS fix)" in text
        assert station.rig.stack.mission.state is MissionState.NONE
    finally:
        station.close()


def test_a_single_goal_pauses_the_mission_and_set_current_drives_it_again(station: Station) -> None:
    rig = station.rig
    station.upload(plan_items())
    station.start()
    mission = rig.stack.mission
    rig.run_until(lambda: mission.current == 1, 40.0, "the first waypoint")
    rig.stack.set_goal(12.0, 12.0)  # Zenoh, a MAVLink DO_REPOSITION, or the operator
    assert mission.state is MissionState.PAUSED
    assert station.details("mission_paused") == ["a single goal replaced the mission at item 1 of 3"]
    assert rig.stack.goal is not None and (rig.stack.goal.x, rig.stack.goal.y) == (12.0, 12.0)
    rig.run_until(lambda: rig.stack.mode is Mode.ARRIVED, 60.0, "the single goal")
    rig.run_for(1.0)
    assert mission.state is MissionState.PAUSED and mission.current == 1  # its arrival is not the mission's
    station.gcs.receive()
    paused = station.gcs.of_type("MISSION_CURRENT")[-1]
    assert (paused.seq, paused.mission_state) == (1, mavlink2.MISSION_STATE_PAUSED)
    station.send(mavlink2.MAVLink_mission_set_current_message(*ROVER, 2))
    assert mission.state is MissionState.ACTIVE and mission.current == 2
    assert station.details("mission_current") == ["item 2 of 3 made current by 255/190"]
    assert rig.stack.goal is not None
    assert (rig.stack.goal.x, rig.stack.goal.y) == pytest.approx(PLAN[2], abs=0.02)
    current = station.gcs.of_type("MISSION_CURRENT")[-1]  # at once, not at the next second
    assert (current.seq, current.mission_state) == (2, mavlink2.MISSION_STATE_ACTIVE)


def test_clearing_the_mission_being_driven_holds_the_rover(station: Station) -> None:
    rig = station.rig
    station.upload(plan_items())
    station.start()
    rig.drive()
    station.send(mavlink2.MAVLink_mission_clear_all_message(*ROVER, MISSION))
    assert station.details("mission_cleared") == ["mission cleared by 255/190: the rover holds"]
    assert rig.stack.mission.state is MissionState.NONE and rig.stack.mode is Mode.IDLE
    assert rig.stack.goal is None and rig.stack.path is None
    rig.run_for(2.0)
    assert abs(rig.body.speed) < 0.05
    # A clear with no mission being driven leaves a single goal alone.
    rig.stack.set_goal(5.0, 5.0)
    station.send(mavlink2.MAVLink_mission_clear_all_message(*ROVER, MISSION))
    assert station.details("mission_cleared")[-1] == "mission cleared by 255/190"
    assert rig.stack.mode is not Mode.IDLE


def test_a_mission_the_trial_hands_over_is_downloadable_as_global_waypoints(station: Station) -> None:
    rig = station.rig
    assert rig.stack.start_mission(PLAN, "test")
    station.send(mavlink2.MAVLink_mission_request_list_message(*ROVER, MISSION))
    assert station.gcs.of_type("MISSION_COUNT")[-1].count == 3
    expected = plan_items()
    for seq in range(3):
        station.send(mavlink2.MAVLink_mission_request_int_message(*ROVER, seq, MISSION))
        item = station.gcs.of_type("MISSION_ITEM_INT")[-1]
        assert (item.seq, item.frame, item.command) == (seq, mavlink2.MAV_FRAME_GLOBAL_INT, 16)
        assert abs(item.x - expected[seq].x) <= 1 and abs(item.y - expected[seq].y) <= 1
    assert station.gcs.of_type("MISSION_ITEM_INT")[0].current == 1  # item 0 is being driven


def test_an_upload_while_parked_waits_for_mission_start(station: Station) -> None:
    rig = station.rig
    rig.run_until(lambda: rig.stack.mode is Mode.ARRIVED, 20.0, "the rig's own goal, where it stands")
    assert station.upload(plan_items()).type == mavlink2.MAV_MISSION_ACCEPTED
    mission = rig.stack.mission
    assert mission.state is MissionState.NOT_STARTED and station.details("mission")[-1].endswith(
        "; not started: MISSION_START or MISSION_SET_CURRENT drives it"
    )
    rig.run_for(3.0)
    assert rig.stack.mode is Mode.ARRIVED and rig.stack.goal is not None
    assert (rig.stack.goal.x, rig.stack.goal.y) == (3.0, 3.0) and abs(rig.body.speed) < 0.05
    station.gcs.receive()
    waiting = station.gcs.of_type("MISSION_CURRENT")[-1]
    assert (waiting.seq, waiting.total, waiting.mission_state) == (0, 3, mavlink2.MISSION_STATE_NOT_STARTED)
    station.start(1)  # from item 1
    assert mission.state is MissionState.ACTIVE and mission.current == 1
    assert rig.stack.goal is not None
    assert (rig.stack.goal.x, rig.stack.goal.y) == pytest.approx(PLAN[1], abs=0.02)


def test_an_upload_while_a_single_goal_or_a_complete_mission_is_there_waits_too(station: Station) -> None:
    rig = station.rig
    rig.stack.set_goal(12.0, 12.0)
    station.upload(plan_items())
    assert rig.stack.goal is not None and (rig.stack.goal.x, rig.stack.goal.y) == (12.0, 12.0)
    assert rig.stack.mission.state is MissionState.NOT_STARTED
    # A mission driven to its end, then a new upload: parked at the end, not driven.
    station.start(2)
    rig.run_until(lambda: rig.stack.mission.state is MissionState.COMPLETE, 60.0, "the mission's end")
    station.upload(plan_items(list(reversed(PLAN))))
    assert rig.stack.mission.state is MissionState.NOT_STARTED and rig.stack.mode is Mode.ARRIVED


def test_an_upload_while_a_mission_is_driven_replaces_it_and_is_driven_from_item_0(station: Station) -> None:
    rig = station.rig
    station.upload(plan_items())
    station.start(2)
    rig.run_for(1.0)
    new_plan = [(8.0, 3.0), (9.0, 6.0)]
    station.upload(plan_items(new_plan))
    mission = rig.stack.mission
    assert mission.state is MissionState.ACTIVE and mission.current == 0 and mission.count == 2
    assert station.details("mission")[-1].endswith(
        "; driven from item 0 in place of the mission being driven"
    )
    assert rig.stack.goal is not None
    assert (rig.stack.goal.x, rig.stack.goal.y) == pytest.approx(new_plan[0], abs=0.02)


def test_the_mission_advancing_by_itself_leaves_a_stall_latch_standing(station: Station) -> None:
    """The stuck and stall latches clear on a goal or item given from outside, not when the mission goes
    on to its next waypoint: a wheel latched stalled at item 0's arrival still holds the rover after."""
    rig = station.rig
    stack = rig.stack
    safety = stack.safety
    driver = stack._mission_driver
    arrive = driver._item_reached

    def latched_at_arrival() -> None:
        if stack.mission.current == 0:
            # The supervisor's own latch, as a wheel's third stall in its window sets it.
            safety._trip(WHEEL_STALLED, "error", "wheel 1 stalled (test): latched until a new goal or resume")
            safety._stall_latched = True
        arrive()

    driver._item_reached = latched_at_arrival  # type: ignore[method-assign]
    station.upload(plan_items())
    station.start()
    rig.run_until(lambda: stack.mission.current == 1, 40.0, "the first waypoint")
    rig.run_for(1.0)
    assert rig.events("failsafe.wheel_stalled") and not rig.events("cleared.wheel_stalled")
    assert stack.safety_mode.value == "HOLD" and abs(rig.body.speed) < 0.05
    # Given from outside: MISSION_SET_CURRENT clears it, as a new goal does.
    station.send(mavlink2.MAVLink_mission_set_current_message(*ROVER, 1))
    assert [m["detail"] for _, m in rig.events("cleared.wheel_stalled")] == ["new goal"]


def test_start_mission_before_the_datum_is_refused() -> None:
    station = _station_without_datum()
    try:
        assert not station.rig.stack.start_mission(PLAN, "test")
        assert station.details("mission_rejected") == [
            "mission from test: no ENU datum yet (no GPS fix), a ground station could not follow it"
        ]
        assert station.rig.stack.mission.state is MissionState.NONE
    finally:
        station.close()


def speed_plan() -> list[Any]:
    """PLAN with speed changes: 0.5 m/s before the first waypoint, back to the default before the last."""
    first, second, third = plan_items()
    for item, seq in ((first, 1), (second, 2), (third, 4)):
        item.seq = seq
    return [change_speed(0, 0.5), first, second, change_speed(3, -2.0), third]


def state_records(rig: Rig, after_ns: int) -> list[dict[str, Any]]:
    return [m for topic, t, m in rig.sink.records if topic == "navigator/state" and t > after_ns]


def set_current(station: Station, seq: int) -> None:
    station.send(mavlink2.MAVLink_mission_set_current_message(*ROVER, seq))


def test_a_speed_change_limits_the_mission_and_a_single_goal_lifts_it_until_resumed(station: Station) -> None:
    rig = station.rig
    stack = rig.stack
    assert station.upload(speed_plan()).type == mavlink2.MAV_MISSION_ACCEPTED
    assert station.details("mission")[-1].startswith(
        "mission of 5 items (3 waypoints, 2 speed changes) from MAVLink upload by 255/190 on the "
        "ground_station link: speed 0.50 m/s, (6.00, 4.00), (7.00, 8.00), speed default, (4.00, 9.0"
    )
    station.start()
    # Item 0 applied at once, the mission on to item 1 in the same tick; the ground station told.
    mission = stack.mission
    assert (mission.state, mission.current, mission.count) == (MissionState.ACTIVE, 1, 5)
    assert station.details("mission_speed") == ["item 0 of 5: mission speed limit 0.50 m/s"]
    assert stack.guidance.core.mission_speed_mps == 0.5
    assert [m.seq for m in station.gcs.of_type("MISSION_ITEM_REACHED")] == [0]
    assert station.gcs.of_type("MISSION_CURRENT")[-1].seq == 1
    started = rig.drive()
    rig.run_for(2.0)
    states = state_records(rig, started)
    assert max(s["target_speed_mps"] for s in states) <= 0.5
    assert any(s["speed_limit_reason"] == "mission_speed" for s in states)
    # A single goal pauses the mission and lifts its limit: the spec's speed lasts "until it is overridden
    # or there is a mode change", and ArduPilot's Guided mode and PX4 reset it when leaving the mission.
    stack.set_goal(12.0, 12.0)
    paused = rig.run_until(lambda: stack.safety_mode.value == "DRIVING", 5.0, "the single goal driven")
    rig.run_for(2.0)
    assert mission.state is MissionState.PAUSED and stack.guidance.core.mission_speed_mps is None
    assert station.details("mission_speed")[-1] == (
        "mission speed limit 0.50 m/s lifted: a single goal paused the mission"
    )
    assert all(s["speed_limit_reason"] != "mission_speed" for s in state_records(rig, paused))
    # Resumed at item 1, where it was paused: the speed in force then (item 0's) comes back with it.
    set_current(station, 1)
    assert mission.state is MissionState.ACTIVE and stack.guidance.core.mission_speed_mps == 0.5
    assert station.details("mission_speed")[-1] == (
        "resumed at item 1: mission speed limit 0.50 m/s, as when it was paused"
    )
    # Cleared: the limit goes with the mission.
    station.send(mavlink2.MAVLink_mission_clear_all_message(*ROVER, MISSION))
    assert stack.guidance.core.mission_speed_mps is None
    assert (
        station.details("mission_speed")[-1] == "mission speed limit 0.50 m/s lifted: the mission was cleared"
    )
    station.gcs.receive()
    assert [m.seq for m in station.gcs.of_type("MISSION_ITEM_REACHED")] == [0]


def test_a_jump_into_the_mission_takes_the_speed_the_items_before_it_set(station: Station) -> None:
    stack = station.rig.stack
    mission = stack.mission
    station.upload(speed_plan())
    station.start()
    # Past the speed change back to the default: item 4 is driven at the speed the mission sets there,
    # as PX4 replays the last speed change before the item it resumes at.
    set_current(station, 4)
    assert mission.current == 4 and stack.guidance.core.mission_speed_mps is None
    assert station.details("mission_speed")[-1] == (
        "item 3 before item 4: back to the default speed: no mission speed limit"
    )
    # Back into the slow stretch (item 2, after the 0.5 m/s at item 0): slow again, told once.
    set_current(station, 2)
    assert mission.current == 2 and stack.guidance.core.mission_speed_mps == 0.5
    assert station.details("mission_speed")[-1] == "item 0 before item 2: mission speed limit 0.50 m/s"
    told = len(station.details("mission_speed"))
    set_current(station, 1)  # the same speed: no event
    assert stack.guidance.core.mission_speed_mps == 0.5 and len(station.details("mission_speed")) == told
    # Naming a speed change that sets the speed applies it alone, not the one before it first.
    set_current(station, 4)
    told = len(station.details("mission_speed"))
    set_current(station, 3)
    assert mission.current == 4 and stack.guidance.core.mission_speed_mps is None
    assert station.details("mission_speed")[told:] == [
        "item 3 of 5: back to the default speed: no mission speed limit"
    ]
    station.gcs.receive()
    assert [m.seq for m in station.gcs.of_type("MISSION_ITEM_REACHED")] == [0, 3]


def test_a_jump_to_a_no_change_item_starts_from_the_speed_before_it(station: Station) -> None:
    stack = station.rig.stack
    first, second, third = plan_items()
    first.seq, second.seq, third.seq = 1, 3, 6
    items = [change_speed(0, 0.5), first, change_speed(2, -2.0), second, change_speed(4, -1.0)]
    station.upload([*items, change_speed(5, 0.3), third])
    station.start()
    told = len(station.details("mission_speed"))
    set_current(station, 4)  # "no change", then 0.3: the speed it keeps is item 2's default
    assert station.details("mission_speed")[told:] == [
        "item 2 before item 4: back to the default speed: no mission speed limit",
        "item 4 of 7: speed unchanged (DO_CHANGE_SPEED -1): the mission's limit stays none",
        "item 5 of 7: mission speed limit 0.30 m/s",
    ]
    assert stack.mission.current == 6  # the speed came as float32:
    assert stack.guidance.core.mission_speed_mps == pytest.approx(0.3)


def test_the_stack_refuses_a_mission_speed_below_its_stuck_and_stall_checks(station: Station) -> None:
    (first,) = plan_items(PLAN[:1])
    first.seq = 1
    # The default config: stuck_min_command_mps 0.2 is the largest of the three floors.
    refused = station.upload([change_speed(0, 0.15), first])
    assert refused.type == mavlink2.MAV_MISSION_INVALID_PARAM2
    assert station.upload([change_speed(0, 0.2), first]).type == mavlink2.MAV_MISSION_ACCEPTED


def test_a_no_change_speed_item_keeps_the_limit_in_force(station: Station) -> None:
    stack = station.rig.stack
    first, second = plan_items(PLAN[:2])
    first.seq, second.seq = 1, 3
    items = [change_speed(0, 0.5), first, change_speed(2, -1.0), second]
    assert station.upload(items).type == mavlink2.MAV_MISSION_ACCEPTED
    station.start()
    assert stack.guidance.core.mission_speed_mps == 0.5
    set_current(station, 2)  # the "no change" item: applied, the limit item 0 set stays
    assert stack.mission.current == 3 and stack.guidance.core.mission_speed_mps == 0.5
    assert station.details("mission_speed")[-1] == (
        "item 2 of 4: speed unchanged (DO_CHANGE_SPEED -1): the mission's limit stays 0.50 m/s"
    )


def test_a_replaced_mission_takes_its_limit_along_and_a_last_speed_change_completes_it(
    station: Station,
) -> None:
    stack = station.rig.stack
    station.upload(speed_plan())
    station.start()
    assert stack.guidance.core.mission_speed_mps == 0.5
    # An upload in place of the mission being driven: the old limit lifted, the new mission's applied.
    (first,) = plan_items(PLAN[:1])
    assert station.upload([first, change_speed(1, 5.0)]).type == mavlink2.MAV_MISSION_ACCEPTED
    assert (
        station.details("mission_speed")[-1]
        == "mission speed limit 0.50 m/s lifted: the mission was replaced"
    )
    assert stack.guidance.core.mission_speed_mps is None and stack.mission.current == 0
    # Item 1, a speed change after the last waypoint: above the rover's top speed (that stands), then the
    # end, which lifts it: nothing left to drive, the rover holds.
    station.send(mavlink2.MAVLink_mission_set_current_message(*ROVER, 1))
    assert station.details("mission_speed")[-2:] == [
        "item 1 of 2: mission speed limit 5.00 m/s: at or above the rover's max_speed_mps 1.00, which stays "
        "its limit",
        "mission speed limit 5.00 m/s lifted: the mission is complete",
    ]
    assert station.details("mission_complete") == [
        "mission complete: no waypoint from item 1: the rover holds"
    ]
    assert stack.mission.state is MissionState.COMPLETE and stack.mode is Mode.IDLE
    assert stack.guidance.core.mission_speed_mps is None
