"""Missions in the onboard stack: uploaded by a ground station over MAVLink, driven waypoint by waypoint on
the lockstep rig (the real stack against the simulated rover), replaced by a single goal, resumed, cleared,
refused whole when a waypoint is outside the geofence or the rover has no datum yet."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from estimator.geodesy import Datum, to_geodetic
from firmware_bridge.mavlink_transport import memory_pipe_pair
from navigator.mission import MissionState
from navigator.onboard import Mode
from tests.firmware_bridge.ground_station import MISSION, ROVER, GroundStation, waypoint
from tests.runtime.rig import DATUM, MSG_GPS_RAW_INT, Rig, rig_config

# ENU metres on the rig's open 20 m x 20 m map; the rover starts at (3, 3).
PLAN = [(6.0, 4.0), (7.0, 8.0), (4.0, 9.0)]


def plan_items(plan: list[tuple[float, float]] = PLAN) -> list[Any]:
    datum = Datum(*DATUM)
    return [waypoint(seq, *to_geodetic(datum, x, y, 0.0)[:2]) for seq, (x, y) in enumerate(plan)]


def flat(points: Any) -> list[float]:
    return [float(c) for point in points for c in point]


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

    def send(self, msg: Any) -> None:
        self.gcs.send(msg)
        self.rig.control_tick()
        self.gcs.receive()

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


def test_a_waypoint_outside_the_geofence_refuses_the_upload_and_keeps_the_mission() -> None:
    fence = ((1.0, 1.0), (10.0, 1.0), (10.0, 10.0), (1.0, 10.0))
    station = Station(config=rig_config(fence=fence))
    try:
        assert station.upload(plan_items()).type == mavlink2.MAV_MISSION_ACCEPTED
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


def test_an_upload_before_the_rover_knows_its_datum_is_refused() -> None:
    config = rig_config()
    config = dataclasses.replace(
        config,
        estimator=dataclasses.replace(
            config.estimator, datum_lat_deg=None, datum_lon_deg=None, datum_alt_m=None
        ),
    )
    station = Station(config=config)
    try:
        station.rig.wire.dropped.add(MSG_GPS_RAW_INT)  # no fix: no datum
        assert station.upload(plan_items()).type == mavlink2.MAV_MISSION_DENIED
        text = "".join(m.text for m in station.gcs.of_type("STATUSTEXT"))
        assert "item 0: no ENU datum yet (no GPS fix)" in text
        assert station.rig.stack.mission.state is MissionState.NONE
    finally:
        station.close()


def test_a_single_goal_pauses_the_mission_and_set_current_drives_it_again(station: Station) -> None:
    rig = station.rig
    station.upload(plan_items())
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
