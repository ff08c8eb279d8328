"""Jumps (MAV_CMD_DO_JUMP) and delays (MAV_CMD_NAV_DELAY) in the onboard stack, uploaded by a ground station
and driven on the lockstep rig: the order of the items driven, what the ground station is told, the speed a
loop drives at, the counts kept by a resume and started again by MISSION_START, a loop for ever that
advances at most an item a tick, and a delay that holds the rover where it is for its time."""

from __future__ import annotations

from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from estimator.geodesy import Datum, to_geodetic
from navigator.mission import Mission, MissionState
from tests.firmware_bridge.ground_station import change_speed, do_jump, nav_delay, waypoint
from tests.navigator.test_onboard_mission import Station, set_current, state_records
from tests.runtime.rig import DATUM

# ENU metres on the rig's open map; the rover starts at (3, 3). A short lap, then somewhere else.
A, B, C = (5.0, 3.0), (5.0, 5.0), (3.0, 6.0)


@pytest.fixture
def station() -> Any:
    made = Station()
    yield made
    made.close()


def at(seq: int, point: tuple[float, float]) -> Any:
    lat, lon, _ = to_geodetic(Datum(*DATUM), *point, 0.0)
    return waypoint(seq, lat, lon)


def reached(made: Station) -> list[int]:
    """The items the mission reported reached, in order (from its events: waypoints and delays)."""
    return [int(d.split(" of ")[0].removeprefix("item ")) for d in made.details("mission_item_reached")]


def on_lap_two(station: Station) -> tuple[Any, Mission]:
    """``A, B, jump to item 0 once, C`` uploaded, started and driven to its jump: the rover on lap 2."""
    rig = station.rig
    mission = rig.stack.mission
    station.upload([at(0, A), at(1, B), do_jump(2, 0, 1), at(3, C)])
    station.start()
    rig.run_until(lambda: mission.jumps_done(2) == 1, 40.0, "the jump")
    return rig, mission


def test_a_two_waypoint_loop_jumped_twice_drives_a_b_a_b_a_b_then_the_item_after(station: Station) -> None:
    rig = station.rig
    mission = rig.stack.mission
    plan = [at(0, A), change_speed(1, 0.5), at(2, B), do_jump(3, 0, 2), change_speed(4, -2.0), at(5, C)]
    assert station.upload(plan).type == mavlink2.MAV_MISSION_ACCEPTED
    assert station.details("mission")[-1].endswith(
        "(5.00, 3.00), speed 0.50 m/s, (5.00, 5.00), jump to item 0 2 times, speed default, (3.00, 6.00); "
        "not started: MISSION_START or MISSION_SET_CURRENT drives it"
    )
    station.start()
    # Round again: A is driven at the speed the items driven so far left (0.5 m/s), not the none a fresh
    # start at item 0 would have.
    rig.run_until(lambda: mission.jumps_done(3) == 1, 40.0, "the first jump")
    assert mission.current == 0 and rig.stack.guidance.core.mission_speed_mps == 0.5
    rig.run_until(lambda: mission.state is MissionState.COMPLETE, 60.0, "the mission's end")
    assert reached(station) == [0, 2, 0, 2, 0, 2, 5]
    station.gcs.receive()
    # The ground station is told each speed change passed too, as it is without jumps.
    assert [m.seq for m in station.gcs.of_type("MISSION_ITEM_REACHED")] == [0, 1, 2] * 3 + [4, 5]
    # The jump is never current: MISSION_CURRENT and navigator/state name the items driven to.
    assert 3 not in {m.seq for m in station.gcs.of_type("MISSION_CURRENT")}
    currents = [s["mission"]["current"] for s in state_records(rig, 0) if "mission" in s]
    assert 3 not in currents and currents.count(0) > 0
    assert station.details("mission_jump") == [
        "item 3 of 6: jump to item 0 (1 of 2)",
        "item 3 of 6: jump to item 0 (2 of 2)",
        "item 3 of 6: jumped to item 0 2 of 2 times: on past it",
    ]
    assert rig.stack.guidance.core.mission_speed_mps is None


def test_a_resume_after_a_single_goal_keeps_the_count_and_mission_start_begins_it_again(
    station: Station,
) -> None:
    rig, mission = on_lap_two(station)
    rig.stack.set_goal(3.0, 3.0)  # the operator takes over on the second lap...
    rig.run_for(0.5)
    set_current(station, 0)  # ...and resumes it: the lap driven counts, one lap left, not two
    assert mission.state is MissionState.ACTIVE and mission.jumps_done(2) == 1
    rig.run_until(lambda: mission.state is MissionState.COMPLETE, 60.0, "the mission's end")
    assert reached(station) == [0, 1, 0, 1, 3]
    station.start()  # a new run: the laps again
    assert mission.jumps_done(2) == 0
    rig.run_until(lambda: mission.jumps_done(2) == 1, 40.0, "the jump of the new run")


def test_a_resume_on_lap_two_drives_at_the_speed_it_was_paused_at(station: Station) -> None:
    # Lap 1 leaves the speed at 0.5 m/s; on lap 2 the operator takes over at A and resumes there. The list
    # before item 0 holds no speed change, so replaying it would lift the limit: the rover would drive
    # lap 2's rest faster than the lap it was driving.
    rig = station.rig
    mission = rig.stack.mission
    station.upload([at(0, A), at(1, B), change_speed(2, 0.5), do_jump(3, 0, 1), at(4, C)])
    station.start()
    rig.run_until(lambda: mission.jumps_done(3) == 1, 60.0, "the jump")
    assert mission.current == 0 and rig.stack.guidance.core.mission_speed_mps == 0.5
    rig.stack.set_goal(3.0, 3.0)
    assert rig.stack.guidance.core.mission_speed_mps is None  # a single goal lifts it
    rig.run_for(0.5)
    set_current(station, 0)
    assert rig.stack.guidance.core.mission_speed_mps == 0.5
    assert station.details("mission_speed")[-1] == (
        "resumed at item 0: mission speed limit 0.50 m/s, as when it was paused"
    )


def test_mission_start_elsewhere_on_a_paused_mission_is_a_new_run(station: Station) -> None:
    # Paused on lap 2, then started at item 0 (not where it was paused): the laps again, not item 0 with
    # lap 2's count (which would drive one lap fewer than either a resume or a new run).
    rig, mission = on_lap_two(station)
    assert mission.current == 0  # lap 2 under way
    rig.run_until(lambda: mission.current == 1, 40.0, "lap 2 at B")
    rig.stack.set_goal(3.0, 3.0)
    rig.run_for(0.5)
    assert mission.state is MissionState.PAUSED and mission.current == 1
    station.start(0)
    assert mission.jumps_done(2) == 0
    rig.run_until(lambda: mission.state is MissionState.COMPLETE, 90.0, "the mission's end")
    assert reached(station)[-5:] == [0, 1, 0, 1, 3]


def test_a_loop_for_ever_advances_at_most_an_item_a_tick(station: Station) -> None:
    rig = station.rig
    mission = rig.stack.mission
    # A waypoint where the rover stands, jumped to for ever: reached at once each time, yet each control
    # tick ends, with at most one pass round the loop.
    station.upload([at(0, (3.0, 3.0)), do_jump(1, 0, -1)])
    station.start()
    ticks = 100
    rig.run_for(ticks * 0.02)
    assert mission.state is MissionState.ACTIVE and mission.current == 0
    laps = mission.jumps_done(1)
    assert 1 <= laps <= ticks


def test_a_delay_holds_the_rover_where_it_is_for_its_time_then_goes_on(station: Station) -> None:
    rig = station.rig
    mission = rig.stack.mission
    station.upload([at(0, A), nav_delay(1, 2.0), at(2, B)])
    station.start()
    began = rig.run_until(lambda: bool(station.details("mission_delay")), 30.0, "the delay")
    assert station.details("mission_delay") == ["item 1 of 3: waiting 2 s, the rover held where it is"]
    went_on = rig.run_until(lambda: mission.current == 2, 5.0, "the mission going on")
    assert 2_000_000_000 <= went_on - began <= 2_000_000_000 + 40_000_000
    waiting = [
        m
        for topic, t, m in rig.sink.records
        if topic == "navigator/state" and began + 500_000_000 < t < went_on
    ]
    assert waiting and all(m["mission"]["current"] == 1 and m["target_speed_mps"] == 0.0 for m in waiting)
    station.gcs.receive()
    assert any(m.seq == 1 for m in station.gcs.of_type("MISSION_CURRENT"))
    rig.run_until(lambda: mission.state is MissionState.COMPLETE, 30.0, "the mission's end")
    assert station.details("mission_item_reached")[1] == "item 1 of 3 (delay 2 s) done"
    station.gcs.receive()
    assert [m.seq for m in station.gcs.of_type("MISSION_ITEM_REACHED")] == [0, 1, 2]


def test_a_delay_first_holds_a_parked_rover(station: Station) -> None:
    rig = station.rig
    mission = rig.stack.mission
    station.upload([nav_delay(0, 1.0), at(1, A)])
    station.start()
    assert mission.current == 0 and rig.stack.guidance.goal is None
    rig.run_for(0.9)
    assert mission.current == 0 and abs(rig.body.x - 3.0) < 0.05
    rig.run_until(lambda: mission.current == 1, 0.2, "the delay's end")


def test_set_current_within_a_mission_driven_keeps_the_count_and_on_a_complete_one_begins_it_again(
    station: Station,
) -> None:
    rig, mission = on_lap_two(station)
    set_current(station, 1)  # the spec: MISSION_SET_CURRENT does not reset the jump counters
    assert mission.state is MissionState.ACTIVE and mission.jumps_done(2) == 1
    rig.run_until(lambda: mission.state is MissionState.COMPLETE, 40.0, "the mission's end")
    set_current(station, 0)  # a complete mission driven again: a new run
    assert mission.state is MissionState.ACTIVE and mission.jumps_done(2) == 0
