"""Home in the onboard stack, on the lockstep rig with a ground station on its second link: where the
first healthy estimate put the rover, told as HOME_POSITION; moved by DO_SET_HOME (current or given,
refused outside the geofence); MAV_CMD_NAV_RETURN_TO_LAUNCH as a command (a single goal home) and as a
mission item (home, then on to the next item); the loiter items (a timed hold, and one the operator
ends)."""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from estimator.geodesy import Datum, to_geodetic
from firmware_bridge.mavlink_mission import MissionMessage
from navigator.mission import MissionState
from navigator.route_guidance import Mode
from tests.firmware_bridge.ground_station import MISSION, ROVER, command_long, loiter, return_to_launch
from tests.navigator.test_onboard_mission import (
    PLAN,
    Station,
    _station_without_datum,
    plan_items,
    set_current,
)
from tests.runtime.rig import DATUM, rig_config

HOME_POSITION = float(mavlink2.MAVLINK_MSG_ID_HOME_POSITION)
GET_HOME = command_long(mavlink2.MAV_CMD_REQUEST_MESSAGE, HOME_POSITION)
RTL = command_long(mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH)


@pytest.fixture
def station() -> Any:
    made = Station()
    yield made
    made.close()


def answers(received: list[Any]) -> tuple[Any, list[Any]]:
    """The one COMMAND_ACK among ``received`` and the HOME_POSITIONs."""
    (ack,) = [m for m in received if m.get_type() == "COMMAND_ACK"]
    return ack, [m for m in received if m.get_type() == "HOME_POSITION"]


def geodetic(x: float, y: float) -> tuple[float, float]:
    lat, lon, _ = to_geodetic(Datum(*DATUM), x, y, 0.0)
    return lat, lon


def home_xy(station: Station) -> tuple[float, float]:
    """Home in ENU metres, as the HOME_POSITION answering a request tells it (NED; the last one: a ground
    station following the mission was also told when home was first used)."""
    _, homes = answers(station.send(GET_HOME))
    return homes[-1].y, homes[-1].x


def test_home_is_the_first_healthy_estimate_of_where_the_rover_stood(station: Station) -> None:
    rig = station.rig
    rig.run_for(1.0)
    assert station.details("home") == []  # not needed yet: a trial that never uses home records none
    ack, (home,) = answers(station.send(GET_HOME))
    assert (ack.command, ack.result) == (mavlink2.MAV_CMD_REQUEST_MESSAGE, mavlink2.MAV_RESULT_ACCEPTED)
    (detail,) = station.details("home")
    assert detail.startswith("home at (") and "the rover's position estimate at " in detail, detail
    assert detail.endswith("s, its first healthy one")
    x, y = home.y, home.x  # NED
    assert math.hypot(x - 3.0, y - 3.0) < 1.5  # the rig's start (it has not moved), within GPS noise
    lat, lon = geodetic(x, y)
    assert (home.latitude, home.longitude) == (round(lat * 1e7), round(lon * 1e7))
    assert (home.z, home.altitude) == (0.0, round(DATUM[2] * 1000))  # on the ground plane, at the datum
    # The deprecated command is answered the same way, and home is announced once.
    ack, (again,) = answers(station.send(command_long(mavlink2.MAV_CMD_GET_HOME_POSITION)))
    assert ack.result == mavlink2.MAV_RESULT_ACCEPTED and again.latitude == home.latitude
    assert len(station.details("home")) == 1


def test_no_home_before_a_fix_refuses_the_request_and_the_return() -> None:
    station = _station_without_datum()
    try:
        for command in (GET_HOME, RTL, command_long(mavlink2.MAV_CMD_DO_SET_HOME, 1.0)):
            ack, homes = answers(received := station.send(command))
            assert ack.result == mavlink2.MAV_RESULT_TEMPORARILY_REJECTED and homes == []
            text = "".join(m.text for m in received if m.get_type() == "STATUSTEXT")
            assert text.startswith("refused: ") and ("no home yet" in text or "not known yet" in text), text
        ground_link = station.rig.stack._ground_station
        assert ground_link is not None and ground_link.counters.commands_rejected == 3
        assert station.details("home") == [] and station.details("return_to_launch") == []
    finally:
        station.close()


def test_set_home_moves_it_to_the_current_or_given_position_inside_the_fence() -> None:
    fence = ((1.0, 1.0), (19.0, 1.0), (19.0, 19.0), (1.0, 19.0))
    station = Station(config=rig_config(fence=fence))
    try:
        station.rig.run_for(1.0)
        ack, (home,) = answers(station.send(command_long(mavlink2.MAV_CMD_DO_SET_HOME, 1.0)))
        assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
        pose = station.rig.stack.estimator.pose()
        assert pose is not None and (home.y, home.x) == pytest.approx((pose.x, pose.y), abs=0.05)
        assert station.details("home")[-1].startswith("home at (")
        lat, lon = geodetic(10.0, 12.0)
        # COMMAND_INT: a COMMAND_LONG's float32 degrees place it only to ~0.5 m.
        given = mavlink2.MAVLink_command_int_message(
            *ROVER, mavlink2.MAV_FRAME_GLOBAL, mavlink2.MAV_CMD_DO_SET_HOME, 0, 0, 0.0, 0, 0, 0,
            round(lat * 1e7), round(lon * 1e7), 123.0,
        )  # fmt: skip
        ack, (home,) = answers(station.send(given))
        assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
        assert (home.y, home.x, home.z) == pytest.approx((10.0, 12.0, 0.0), abs=0.01)
        assert home.altitude == round(DATUM[2] * 1000)  # placed as goals are: the altitude is not used
        assert (
            station.details("home")[-1].startswith("home moved to (")
            and "by 255/190" in station.details("home")[-1]
        )
        # Outside the fence: denied, home stays.
        lat, lon = geodetic(25.0, 5.0)
        received = station.send(
            command_long(mavlink2.MAV_CMD_DO_SET_HOME, 0.0, 0, 0, 0, lat, lon)
        )  # float32: ~0.5 m
        ack, homes = answers(received)
        assert ack.result == mavlink2.MAV_RESULT_DENIED and homes == []
        assert "is outside the geofence" in "".join(m.text for m in received if m.get_type() == "STATUSTEXT")
        ack, (home,) = answers(station.send(GET_HOME))
        assert (home.y, home.x) == pytest.approx((10.0, 12.0), abs=0.01)
    finally:
        station.close()


def test_return_to_launch_pauses_the_mission_and_drives_home(station: Station) -> None:
    rig = station.rig
    station.upload(plan_items())
    station.start()
    mission = rig.stack.mission
    rig.run_until(lambda: mission.current == 1, 30.0, "the first waypoint")
    ack, _ = answers(station.send(RTL))
    assert (ack.command, ack.result) == (mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink2.MAV_RESULT_ACCEPTED)
    assert mission.state is MissionState.PAUSED
    x, y = home_xy(station)
    assert station.details("return_to_launch") == [f"return to launch by 255/190: home ({x:.2f}, {y:.2f})"]
    rig.run_until(lambda: rig.stack.mode is Mode.ARRIVED, 30.0, "home")
    assert math.hypot(rig.body.x - x, rig.body.y - y) < 0.6
    assert mission.state is MissionState.PAUSED and mission.current == 1  # set current drives it again


def test_a_mission_ending_in_return_to_launch_ends_at_home(station: Station) -> None:
    rig = station.rig
    items = [*plan_items(PLAN[:1]), return_to_launch(1)]
    assert station.upload(items).type == mavlink2.MAV_MISSION_ACCEPTED
    assert station.details("mission")[-1].startswith(
        "mission of 2 items (1 waypoint, 1 return to launch) from MAVLink upload by 255/190 on the "
        "ground_station link: (6.00, 4.00), return to launch; not started"
    )
    station.start()
    mission = rig.stack.mission
    rig.run_until(lambda: mission.state is MissionState.COMPLETE, 60.0, "the mission's end")
    assert mission.current == 1 and rig.stack.mode is Mode.ARRIVED
    x, y = home_xy(station)
    assert math.hypot(rig.body.x - x, rig.body.y - y) < 0.6
    assert station.details("return_to_launch") == [f"item 1 of 2: return to launch: home ({x:.2f}, {y:.2f})"]
    assert station.details("mission_item_reached")[-1].startswith("item 1 of 2 (return to launch) home (")
    assert station.details("mission_complete") == [
        "mission complete: returned to launch at item 1: the rover holds at home"
    ]
    station.gcs.receive()
    assert [m.seq for m in station.gcs.of_type("MISSION_ITEM_REACHED")] == [0, 1]
    last = station.gcs.of_type("MISSION_CURRENT")[-1]
    assert (last.seq, last.total, last.mission_state) == (2, 2, mavlink2.MISSION_STATE_COMPLETE)


def test_after_a_return_to_launch_the_mission_goes_on_to_its_next_item(station: Station) -> None:
    rig = station.rig
    items = [*plan_items(PLAN[:1]), return_to_launch(1), *plan_items(PLAN[1:2])]
    items[2].seq = 2
    assert station.upload(items).type == mavlink2.MAV_MISSION_ACCEPTED
    station.start()
    mission = rig.stack.mission
    rig.run_until(lambda: mission.current == 2, 60.0, "the item after the return")
    assert mission.state is MissionState.ACTIVE and station.details("mission_complete") == []
    assert station.details("mission_item_reached")[-1].startswith("item 1 of 3 (return to launch) home (")
    rig.run_until(lambda: mission.state is MissionState.COMPLETE, 60.0, "the mission's end")
    assert math.hypot(rig.body.x - PLAN[1][0], rig.body.y - PLAN[1][1]) < 0.6
    assert station.details("mission_complete") == ["mission complete: its 2 waypoint(s) reached"]
    station.gcs.receive()
    assert [m.seq for m in station.gcs.of_type("MISSION_ITEM_REACHED")] == [0, 1, 2]


def test_a_timed_loiter_holds_as_a_waypoint_does(station: Station) -> None:
    rig = station.rig
    lat, lon = geodetic(*PLAN[0])
    items = [loiter(0, lat, lon, 2.0), *plan_items(PLAN[1:2])]
    items[1].seq = 1
    assert station.upload(items).type == mavlink2.MAV_MISSION_ACCEPTED
    station.start()
    mission = rig.stack.mission
    arrived = rig.run_until(lambda: bool(station.details("mission_hold")), 30.0, "the loiter")
    assert station.details("mission_hold") == ["item 0 of 2: holding 2 s"]
    went_on = rig.run_until(lambda: mission.current == 1, 5.0, "the mission going on")
    assert 2_000_000_000 <= went_on - arrived <= 2_040_000_000


def test_an_unlimited_loiter_holds_until_the_operator_moves_the_mission_on(station: Station) -> None:
    rig = station.rig
    lat, lon = geodetic(*PLAN[0])
    items = [loiter(0, lat, lon), *plan_items(PLAN[1:2])]
    items[1].seq = 1
    assert station.upload(items).type == mavlink2.MAV_MISSION_ACCEPTED
    assert "(6.00, 4.00) hold until moved on, (7.00, 8.00)" in station.details("mission")[-1]
    station.start()
    mission = rig.stack.mission
    rig.run_until(lambda: bool(station.details("mission_hold")), 30.0, "the loiter")
    assert station.details("mission_hold") == [
        "item 0 of 2: holding until the operator moves the mission on (loiter unlimited)"
    ]
    rig.run_for(20.0)
    assert (mission.state, mission.current) == (MissionState.ACTIVE, 0)
    assert math.hypot(rig.body.x - PLAN[0][0], rig.body.y - PLAN[0][1]) < 0.6
    set_current(station, 1)
    rig.run_until(lambda: mission.state is MissionState.COMPLETE, 30.0, "the next waypoint")
    assert math.hypot(rig.body.x - PLAN[1][0], rig.body.y - PLAN[1][1]) < 0.6


def test_a_home_request_for_another_component_is_not_ours(station: Station) -> None:
    received = station.send(
        command_long(mavlink2.MAV_CMD_REQUEST_MESSAGE, HOME_POSITION, target=(ROVER[0], 1))
    )
    assert [m for m in received if m.get_type() in ("COMMAND_ACK", "HOME_POSITION")] == []


def test_a_new_home_is_told_to_the_ground_stations_following_the_mission_not_the_autopilot(
    station: Station, monkeypatch: pytest.MonkeyPatch
) -> None:
    rig = station.rig
    stack = rig.stack
    assert station.upload(plan_items()).type == mavlink2.MAV_MISSION_ACCEPTED  # it follows the mission now
    autopilot, driver = stack._mavlink, stack._mission_driver
    # A mission partner on the autopilot's link as well (a ground station routed through the autopilot).
    request_list = mavlink2.MAVLink_mission_request_list_message(*ROVER, MISSION)
    driver.take_message(autopilot, MissionMessage(request_list, rig.now_ns))
    to_autopilot: list[Any] = []
    monkeypatch.setattr(autopilot, "send", to_autopilot.append)
    # Moved by the ground station: its answer once on its own link; the autopilot's link is never told.
    ack, (_,) = answers(station.send(command_long(mavlink2.MAV_CMD_DO_SET_HOME, 1.0)))
    assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
    assert [m.get_type() for m in to_autopilot if m.get_type() == "HOME_POSITION"] == []
    # Moved from elsewhere (the partner behind the autopilot): the ground station is told unasked.
    lat, lon = geodetic(10.0, 12.0)
    given = mavlink2.MAVLink_command_int_message(
        *ROVER, mavlink2.MAV_FRAME_GLOBAL, mavlink2.MAV_CMD_DO_SET_HOME, 0, 0, 0.0, 0, 0, 0,
        round(lat * 1e7), round(lon * 1e7), 0.0,
    )  # fmt: skip
    driver.take_message(autopilot, MissionMessage(given, rig.now_ns))
    assert [m.get_type() for m in to_autopilot] == ["COMMAND_ACK", "HOME_POSITION"]  # its answer, once
    rig.control_tick()
    told = [m for m in station.gcs.receive() if m.get_type() in ("COMMAND_ACK", "HOME_POSITION")]
    assert [m.get_type() for m in told] == ["HOME_POSITION"]
    assert (told[0].y, told[0].x) == pytest.approx((10.0, 12.0), abs=0.01)  # NED
    assert station.details("home")[-1].startswith("home moved to (")
