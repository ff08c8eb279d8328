"""A return to launch in a mission, on the lockstep rig with a ground station on its second link: the way
home at the rover's own speed (the mission's speed limit lifted there, set again by the items after it),
and the mission entered at, past, paused and resumed on a return to launch."""

from __future__ import annotations

from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from navigator.mission import MissionState
from tests.firmware_bridge.ground_station import change_speed, command_long, return_to_launch
from tests.navigator.test_onboard_mission import (
    PLAN,
    Station,
    _station_without_datum,
    plan_items,
    set_current,
    state_records,
)
from tests.runtime.rig import rig_config

SLOW_MPS = 0.5


@pytest.fixture
def station() -> Any:
    made = Station()
    yield made
    made.close()


def slow_then_home(*after: Any) -> list[Any]:
    """0.5 m/s (item 0), PLAN[0] (item 1), a return to launch (item 2), then ``after`` (items 3 on)."""
    (first,) = plan_items(PLAN[:1])
    first.seq = 1
    return [change_speed(0, SLOW_MPS), first, return_to_launch(2), *after]


def second_waypoint(seq: int) -> Any:
    (item,) = plan_items(PLAN[1:2])
    item.seq = seq
    return item


def test_the_way_home_lifts_the_mission_speed_limit_and_later_items_set_theirs(station: Station) -> None:
    rig = station.rig
    stack = rig.stack
    plan = slow_then_home(change_speed(3, 0.8), second_waypoint(4))
    assert station.upload(plan).type == mavlink2.MAV_MISSION_ACCEPTED
    station.start()
    mission = stack.mission
    assert stack.guidance.core.mission_speed_mps == SLOW_MPS
    homeward = rig.run_until(lambda: mission.current == 2, 60.0, "the return to launch")
    # ArduPilot's RTL drives at its own speed (RTL_SPEED, else the default), not a mission's slow stretch.
    assert stack.guidance.core.mission_speed_mps is None
    assert station.details("mission_speed")[-1] == (
        "mission speed limit 0.50 m/s lifted: item 2 of 5 returns to launch at the rover's own speed"
    )
    rig.run_until(lambda: mission.current == 4, 60.0, "home, then the item after it")
    on_the_way_home = state_records(rig, homeward)
    assert all(s["speed_limit_reason"] != "mission_speed" for s in on_the_way_home)
    assert max(s["target_speed_mps"] for s in on_the_way_home) > SLOW_MPS + 0.1
    # Past home, the mission's own speed change holds again (float32 on the wire).
    assert stack.guidance.core.mission_speed_mps == pytest.approx(0.8)
    assert station.details("mission_speed")[-1] == "item 3 of 5: mission speed limit 0.80 m/s"


def test_set_current_at_a_return_to_launch_drives_home_at_the_rovers_own_speed(station: Station) -> None:
    stack = station.rig.stack
    assert station.upload(slow_then_home(second_waypoint(3))).type == mavlink2.MAV_MISSION_ACCEPTED
    station.start()
    assert stack.guidance.core.mission_speed_mps == SLOW_MPS
    stack.set_goal(12.0, 12.0)  # a single goal lifts item 0's limit: none is in force when item 2 is set
    assert stack.guidance.core.mission_speed_mps is None
    told = len(station.details("mission_speed"))
    set_current(station, 2)
    mission = stack.mission
    assert (mission.state, mission.current) == (MissionState.ACTIVE, 2)
    # The speed item 0 set is not put back for the way home (no "item 0 before item 2", then lifted again):
    # nothing to lift, nothing said.
    assert station.details("mission_speed")[told:] == []
    assert stack.guidance.core.mission_speed_mps is None
    (home,) = station.details("return_to_launch")
    goal = stack.goal
    assert goal is not None and home.endswith(f"return to launch: home ({goal.x:.2f}, {goal.y:.2f})")


def test_set_current_past_a_return_to_launch_leaves_the_speed_before_it_behind(station: Station) -> None:
    stack = station.rig.stack
    assert station.upload(slow_then_home(second_waypoint(3))).type == mavlink2.MAV_MISSION_ACCEPTED
    station.start()
    assert stack.guidance.core.mission_speed_mps == SLOW_MPS
    set_current(station, 3)
    mission = stack.mission
    assert (mission.state, mission.current) == (MissionState.ACTIVE, 3)
    # Driven from the start, the mission would come to item 3 after the return lifted the 0.5 m/s.
    assert stack.guidance.core.mission_speed_mps is None
    assert station.details("mission_speed")[-1] == "a return to launch before item 3: no mission speed limit"
    assert station.details("return_to_launch") == []  # jumped past, not driven
    goal = stack.goal
    assert goal is not None and (goal.x, goal.y) == pytest.approx(PLAN[1], abs=0.01)


def test_a_return_to_launch_leg_paused_by_a_goal_and_resumed_drives_home_then_goes_on(
    station: Station,
) -> None:
    rig = station.rig
    stack = rig.stack
    (first,) = plan_items(PLAN[:1])
    assert (
        station.upload([first, return_to_launch(1), second_waypoint(2)]).type == mavlink2.MAV_MISSION_ACCEPTED
    )
    station.start()
    mission = stack.mission
    rig.run_until(lambda: mission.current == 1, 60.0, "the way home")
    home = stack.goal
    assert home is not None
    stack.set_goal(12.0, 12.0)
    assert (mission.state, mission.current) == (MissionState.PAUSED, 1)
    assert station.details("mission_paused")[-1] == "a single goal replaced the mission at item 1 of 3"
    rig.run_for(3.0)  # on the way to the single goal: reaching it would not advance the mission
    set_current(station, 1)
    assert (mission.state, mission.current) == (MissionState.ACTIVE, 1)
    resumed = stack.goal
    assert resumed is not None and (resumed.x, resumed.y) == (home.x, home.y)  # home again, as it is
    assert len(station.details("return_to_launch")) == 2
    rig.run_until(lambda: mission.current == 2, 60.0, "home, then the item after it")
    assert station.details("mission_item_reached")[-1].startswith("item 1 of 3 (return to launch) home (")
    rig.run_until(lambda: mission.state is MissionState.COMPLETE, 60.0, "the mission's end")


def test_a_return_to_launch_with_no_home_ends_the_mission_and_the_rover_holds() -> None:
    station = _station_without_datum()  # no fix, no estimate: no home
    try:
        # A return to launch needs no placing: the upload is taken without a datum.
        assert station.upload([return_to_launch(0)]).type == mavlink2.MAV_MISSION_ACCEPTED
        station.start()
        mission = station.rig.stack.mission
        assert (mission.state, mission.current) == (MissionState.COMPLETE, 0)
        assert station.details("return_to_launch") == [
            "item 0 of 1: no home yet (the position estimate has not been healthy yet): the rover holds"
        ]
        assert station.details("mission_complete") == [
            "mission complete: no home to return to at item 0: the rover holds"
        ]
        assert station.rig.stack.goal is None and station.details("home") == []
    finally:
        station.close()


def test_a_return_to_launch_command_is_denied_when_home_is_outside_the_fence() -> None:
    # The fence leaves out the rig's start (3, 3): home, where the rover stood, is outside it.
    station = Station(config=rig_config(fence=((5.0, 5.0), (19.0, 5.0), (19.0, 19.0), (5.0, 19.0))))
    try:
        station.rig.run_for(1.0)
        received = station.send(command_long(mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH))
        (ack,) = [m for m in received if m.get_type() == "COMMAND_ACK"]
        assert (ack.command, ack.result) == (
            mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH,
            mavlink2.MAV_RESULT_DENIED,
        )
        # The ground station also hears the failsafes and mode changes (navigator.event_texts): the refusal's.
        (text,) = [m.text for m in received if m.get_type() == "STATUSTEXT" and m.text.startswith("refused")]
        assert text.startswith("refused: home (") and text.endswith(") is outside the geofence"), text
        ground_link = station.rig.stack._ground_station
        assert ground_link is not None and ground_link.counters.commands_rejected == 1
        assert station.details("return_to_launch") == []  # not driven
    finally:
        station.close()


def test_a_refused_return_to_launch_ends_the_mission_there_whatever_items_follow() -> None:
    # Home, where the rover stood (3, 3), is outside the fence; the waypoint after the return is inside.
    station = Station(config=rig_config(fence=((5.0, 5.0), (19.0, 5.0), (19.0, 19.0), (5.0, 19.0))))
    try:
        station.rig.run_for(1.0)  # the estimate healthy: home is known, and outside the fence
        plan = [return_to_launch(0), change_speed(1, SLOW_MPS), second_waypoint(2)]
        assert station.upload(plan).type == mavlink2.MAV_MISSION_ACCEPTED
        station.start()
        stack = station.rig.stack
        mission = stack.mission
        # Not on to the items after it: the rover holds, the mission COMPLETE at the return item.
        assert (mission.state, mission.current) == (MissionState.COMPLETE, 0)
        assert stack.goal is None and stack.guidance.core.mission_speed_mps is None
        assert station.details("mission_complete") == [
            "mission complete: no home to return to at item 0: the rover holds"
        ]
        station.rig.run_for(1.2)  # MISSION_CURRENT once a second: it says what the event said
        station.gcs.receive()
        last = station.gcs.of_type("MISSION_CURRENT")[-1]
        assert (last.seq, last.total, last.mission_state) == (3, 3, mavlink2.MISSION_STATE_COMPLETE)
        assert mission.state is MissionState.COMPLETE and stack.goal is None
    finally:
        station.close()
