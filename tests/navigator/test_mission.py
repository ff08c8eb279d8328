"""The mission's own bookkeeping: waypoints in order, speed changes passed on the way, the current item,
its states."""

from __future__ import annotations

import math

import pytest

from firmware_bridge.mission_hold import HOLD_UNLIMITED, PlacedWaypoint
from navigator.errors import ParameterError
from navigator.mission import Leg, Mission, MissionState, ReturnToLaunch, SpeedChange, Waypoint

THREE = [(1.0, 2.0), (3.0, 4.0), (5.0, 6.0)]


def test_waypoints_are_driven_in_order_then_the_mission_is_complete() -> None:
    mission = Mission()
    assert mission.state is MissionState.NONE and mission.count == 0
    mission.load(THREE)
    assert (mission.state, mission.current, mission.count) == (MissionState.NOT_STARTED, 0, 3)
    with pytest.raises(ParameterError, match="NOT_STARTED"):
        mission.reached()  # loaded is not driven: no arrival advances it
    assert mission.set_current(0) == Leg((), Waypoint(1.0, 2.0))
    assert (mission.state, mission.current) == (MissionState.ACTIVE, 0)
    assert mission.reached() == Leg((), Waypoint(3.0, 4.0)) and mission.current == 1
    assert mission.reached() == Leg((), Waypoint(5.0, 6.0)) and mission.current == 2
    assert mission.reached() == Leg((), None)
    assert (mission.state, mission.current) == (MissionState.COMPLETE, 2)
    with pytest.raises(ParameterError, match="COMPLETE"):
        mission.reached()


def test_a_single_goal_pauses_it_and_setting_an_item_drives_it_again() -> None:
    mission = Mission()
    assert not mission.pause()  # nothing to pause
    mission.load(THREE)
    assert not mission.pause()  # not started: nothing to pause either
    mission.set_current(0)
    mission.reached()
    assert mission.pause() and mission.state is MissionState.PAUSED and mission.current == 1
    assert not mission.pause()  # once
    with pytest.raises(ParameterError):
        mission.reached()  # a paused mission does not advance on the single goal's arrival
    assert mission.set_current(0).target == Waypoint(1.0, 2.0)
    assert (mission.state, mission.current) == (MissionState.ACTIVE, 0)


def test_a_complete_mission_runs_again_from_the_item_set() -> None:
    mission = Mission()
    mission.load(THREE[:1])
    mission.set_current(0)
    assert mission.reached().target is None and mission.state is MissionState.COMPLETE
    assert mission.set_current(0).target == Waypoint(1.0, 2.0) and mission.state is MissionState.ACTIVE


def test_clear_says_whether_it_was_being_driven() -> None:
    mission = Mission()
    mission.load(THREE)
    assert not mission.clear()  # loaded, not driven
    mission.load(THREE)
    mission.set_current(0)
    assert mission.clear()
    assert (mission.state, mission.count, mission.current) == (MissionState.NONE, 0, 0)
    assert not mission.clear()
    mission.load(THREE)
    mission.set_current(0)
    mission.pause()
    assert not mission.clear()


@pytest.mark.parametrize("seq", [-1, 3, 70000])
def test_an_item_it_does_not_have_cannot_be_made_current(seq: int) -> None:
    mission = Mission()
    with pytest.raises(ParameterError, match="no mission"):
        mission.set_current(0)
    mission.load(THREE)
    mission.set_current(0)
    mission.reached()
    with pytest.raises(ParameterError, match=r"items 0\.\.2"):
        mission.set_current(seq)
    assert (mission.state, mission.current) == (MissionState.ACTIVE, 1)  # unchanged


@pytest.mark.parametrize("waypoints", [[], [(1.0, 2.0), (math.nan, 0.0)], [(math.inf, 1.0)]])
def test_a_bad_mission_is_refused_and_the_one_in_force_kept(waypoints: list[tuple[float, float]]) -> None:
    mission = Mission()
    mission.load(THREE)
    mission.set_current(0)
    with pytest.raises(ParameterError):
        mission.load(waypoints)
    assert mission.waypoints == tuple(Waypoint(*w) for w in THREE) and mission.state is MissionState.ACTIVE


SLOW, DEFAULT, KEEP = SpeedChange(0.4), SpeedChange(None), SpeedChange(None, keep=True)
# Items as uploaded: a speed change first, one between two waypoints, two in a row, one after the last.
WITH_SPEEDS: list[tuple[float, float] | SpeedChange] = [
    SLOW,
    (1.0, 2.0),
    (3.0, 4.0),
    DEFAULT,
    (5.0, 6.0),
    KEEP,
    SLOW,
    (7.0, 8.0),
    DEFAULT,
]


def test_speed_changes_are_numbered_as_uploaded_and_passed_on_the_way_to_the_next_waypoint() -> None:
    mission = Mission()
    mission.load(WITH_SPEEDS)
    assert mission.count == 9 and mission.waypoints == tuple(
        Waypoint(*w) for w in [(1.0, 2.0), (3.0, 4.0), (5.0, 6.0), (7.0, 8.0)]
    )
    # Item 0 is a speed change: applied on the way to item 1, the first waypoint, now current.
    assert mission.set_current(0) == Leg(((0, SLOW),), Waypoint(1.0, 2.0))
    assert (mission.state, mission.current) == (MissionState.ACTIVE, 1)
    assert mission.reached() == Leg((), Waypoint(3.0, 4.0)) and mission.current == 2
    assert mission.reached() == Leg(((3, DEFAULT),), Waypoint(5.0, 6.0)) and mission.current == 4
    assert mission.reached() == Leg(((5, KEEP), (6, SLOW)), Waypoint(7.0, 8.0)) and mission.current == 7
    # The last waypoint reached, a speed change after it: passed, then the end.
    assert mission.reached() == Leg(((8, DEFAULT),), None)
    assert (mission.state, mission.current) == (MissionState.COMPLETE, 8)
    with pytest.raises(ParameterError, match="no waypoint"):
        mission.current_waypoint()


def test_set_current_passes_the_speed_changes_from_the_item_and_says_which_one_set_the_speed_before() -> None:
    mission = Mission()
    mission.load(WITH_SPEEDS)
    # After the speed changes at 0 and 3: the leg passes none; the speed there is item 3's (the default).
    assert mission.set_current(4) == Leg((), Waypoint(5.0, 6.0)) and mission.current == 4
    assert mission.speed_set_before(4) == (3, DEFAULT)
    assert mission.speed_set_before(2) == (0, SLOW) and mission.speed_set_before(0) is None
    # "No change" sets nothing: the last change before item 7 that set the speed is item 6's.
    assert mission.speed_set_before(6) == (3, DEFAULT) and mission.speed_set_before(7) == (6, SLOW)
    # Naming a speed change applies it (and the one after it) on the way to the next waypoint.
    assert mission.set_current(5) == Leg(((5, KEEP), (6, SLOW)), Waypoint(7.0, 8.0))
    assert mission.current_waypoint() == Waypoint(7.0, 8.0)
    # Nothing but a speed change left from the item named: applied, and the mission is complete.
    assert mission.set_current(8) == Leg(((8, DEFAULT),), None)
    assert mission.state is MissionState.COMPLETE


@pytest.mark.parametrize("items", [[SLOW], [SLOW, DEFAULT, KEEP]])
def test_speed_changes_alone_are_no_mission(items: list[SpeedChange]) -> None:
    mission = Mission()
    mission.load(THREE)
    with pytest.raises(ParameterError, match="at least one waypoint"):
        mission.load(items)
    assert mission.count == 3 and mission.state is MissionState.NOT_STARTED


def test_a_waypoints_hold_time_is_kept_and_must_be_a_duration() -> None:
    mission = Mission()
    mission.load([PlacedWaypoint(1.0, 2.0, 5.0), (3.0, 4.0), PlacedWaypoint(5.0, 6.0, HOLD_UNLIMITED)])
    assert mission.waypoints == (
        Waypoint(1.0, 2.0, 5.0),
        Waypoint(3.0, 4.0, 0.0),
        Waypoint(5.0, 6.0, math.inf),
    )
    for bad in (-1.0, math.nan, -math.inf):
        with pytest.raises(ParameterError, match="hold"):
            mission.load([PlacedWaypoint(1.0, 2.0, bad)])
    assert mission.count == 3  # the mission in force kept


def test_a_return_to_launch_is_driven_like_a_waypoint_and_the_mission_goes_on_after_it() -> None:
    mission = Mission()
    slow, fast = SpeedChange(0.5), SpeedChange(1.5)
    # As ArduPilot Rover's Auto: RTL reached (verify_RTL), the mission goes on to the next item.
    mission.load([(1.0, 2.0), slow, ReturnToLaunch(), fast, (9.0, 9.0)])
    assert mission.set_current(0) == Leg((), Waypoint(1.0, 2.0))
    assert mission.reached() == Leg(((1, slow),), ReturnToLaunch()) and mission.current == 2
    assert mission.reached() == Leg(((3, fast),), Waypoint(9.0, 9.0)) and mission.current == 4
    assert mission.state is MissionState.ACTIVE
    assert mission.reached() == Leg((), None)
    assert (mission.state, mission.current) == (MissionState.COMPLETE, 4)


def test_a_return_to_launch_as_the_last_item_completes_the_mission_when_reached() -> None:
    mission = Mission()
    mission.load([(1.0, 2.0), ReturnToLaunch()])
    mission.set_current(0)
    assert mission.reached() == Leg((), ReturnToLaunch())
    assert mission.reached() == Leg((), None)
    assert (mission.state, mission.current) == (MissionState.COMPLETE, 1)


def test_end_here_completes_the_mission_on_its_current_item_whatever_follows() -> None:
    mission = Mission()
    mission.load([ReturnToLaunch(), SpeedChange(0.5), (9.0, 9.0)])
    mission.set_current(0)
    mission.end_here()  # a return to launch with no home to go to
    assert (mission.state, mission.current) == (MissionState.COMPLETE, 0)
    with pytest.raises(ParameterError, match="COMPLETE"):
        mission.end_here()


def test_a_return_to_launch_alone_is_a_mission() -> None:
    mission = Mission()
    mission.load([ReturnToLaunch()])
    assert mission.set_current(0) == Leg((), ReturnToLaunch())
    with pytest.raises(ParameterError, match="at least one waypoint"):
        mission.load([SpeedChange(0.5)])
    assert mission.count == 1
