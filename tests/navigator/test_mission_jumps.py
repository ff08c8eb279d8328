"""The mission's own bookkeeping of jumps and delays: the order of the items driven, the counts and when
they start again, the speed changes a jump skips or repeats, the loops refused, and a walk that stays
bounded whatever the items."""

from __future__ import annotations

import pytest

from firmware_bridge.mavlink_mission import MissionStep
from firmware_bridge.mission_hold import PlacedWaypoint
from firmware_bridge.mission_jump import JUMP_FOREVER
from navigator.errors import ParameterError
from navigator.mission import (
    Delay,
    DrivenItem,
    Jump,
    JumpPassed,
    Leg,
    Mission,
    MissionState,
    ReturnToLaunch,
    SpeedChange,
    Waypoint,
)

A, B, C = Waypoint(1.0, 2.0), Waypoint(3.0, 4.0), Waypoint(5.0, 6.0)
SLOW, DEFAULT = SpeedChange(0.5), SpeedChange(None)


def steps(*items: DrivenItem) -> list[MissionStep]:
    """Items as ``Mission.load`` takes them (a waypoint as placed)."""
    return [PlacedWaypoint(*item) if isinstance(item, Waypoint) else item for item in items]


def driven(
    mission: Mission, first: int = 0, limit: int = 50
) -> list[Waypoint | ReturnToLaunch | Delay | None]:
    """The items the mission makes current, in order, from ``first`` to its end (at most ``limit``)."""
    order = [mission.set_current(first).target]
    while mission.state is MissionState.ACTIVE and len(order) < limit:
        order.append(mission.reached().target)
    return order


def test_a_two_waypoint_loop_jumped_twice_drives_it_three_times_then_goes_on() -> None:
    mission = Mission()
    mission.load(steps(A, B, Jump(0, 2), C))
    assert driven(mission) == [A, B, A, B, A, B, C, None]
    assert mission.jumps_done(2) == 2


def test_the_jump_is_never_current_and_each_pass_is_told() -> None:
    mission = Mission()
    mission.load(steps(A, B, Jump(0, 1), C))
    mission.set_current(0)
    assert mission.reached() == Leg((), B)
    assert mission.reached() == Leg((), A, (JumpPassed(2, Jump(0, 1), 1, True),))
    assert mission.current == 0
    assert mission.reached() == Leg((), B)
    assert mission.reached() == Leg((), C, (JumpPassed(2, Jump(0, 1), 1, False),))
    assert mission.current == 3


def test_a_jump_for_ever_never_goes_past() -> None:
    mission = Mission()
    mission.load(steps(A, B, Jump(0, JUMP_FOREVER), C))
    assert driven(mission, limit=41) == [A, B] * 20 + [A]
    assert mission.state is MissionState.ACTIVE and mission.jumps_done(2) == 20


def test_a_count_of_0_never_jumps_and_a_forward_jump_skips() -> None:
    mission = Mission()
    mission.load(steps(A, Jump(0, 0), Jump(4, 1), B, C))
    assert driven(mission) == [A, C, None]


def test_speed_changes_are_those_of_the_items_driven_a_loop_repeating_them_a_jump_skipping_them() -> None:
    mission = Mission()
    # A at no limit, the 0.5 m/s before B, then round again: A is driven at 0.5 (the items driven so far
    # set it), the change applied again on the way to B; the jump forward skips the default one.
    mission.load(steps(A, SLOW, B, Jump(0, 1), Jump(6, 1), DEFAULT, C))
    mission.set_current(0)
    assert mission.reached() == Leg(((1, SLOW),), B)
    assert mission.reached() == Leg((), A, (JumpPassed(3, Jump(0, 1), 1, True),))
    assert mission.reached() == Leg(((1, SLOW),), B)
    leg = mission.reached()
    assert leg.speed_changes == () and leg.target == C
    assert [j.seq for j in leg.jumps] == [3, 4]


def test_the_counts_start_again_on_a_new_run_and_go_on_on_a_resume() -> None:
    mission = Mission()
    mission.load(steps(A, B, Jump(0, 2), C))
    mission.set_current(0)
    mission.reached()
    mission.reached()  # round once: A current again
    assert mission.jumps_done(2) == 1
    mission.pause()
    mission.set_current(0, restart=False)  # a resume: one jump left
    assert [mission.reached().target for _ in range(4)] == [B, A, B, C]
    mission.set_current(0)  # a new run: two jumps again
    assert mission.jumps_done(2) == 0
    assert [mission.reached().target for _ in range(6)] == [B, A, B, A, B, C]
    mission.load(steps(A, B, Jump(0, 2), C))
    assert mission.jumps_done(2) == 0


def test_setting_a_jump_current_takes_it() -> None:
    mission = Mission()
    mission.load(steps(A, B, Jump(0, 1), C))
    assert mission.set_current(2).target == A and mission.jumps_done(2) == 1


def test_a_delay_is_current_until_reached() -> None:
    mission = Mission()
    mission.load(steps(A, Delay(2.0), SLOW, B))
    mission.set_current(0)
    assert mission.reached() == Leg((), Delay(2.0)) and mission.current == 1
    assert mission.reached() == Leg(((2, SLOW),), B)


@pytest.mark.parametrize(
    ("items", "match"),
    [
        ([A, Jump(1, 1)], "the loop from item 1 back to item 1 has no waypoint"),
        ([A, Jump(2, -1), Jump(1, -1), B], "the loop from item 1 back to item 2"),
        ([A, SLOW, Delay(1.0), Jump(1, 3)], "the loop from item 1 back to item 3"),
        ([A, Jump(5, 1)], "jumps nowhere in the mission"),
        ([A, Jump(0, -2)], "repeats -2 times \\(0 or more, or -1: for ever\\)"),
        ([A, Delay(float("nan"))], "delay nan s is not a duration"),
        ([Delay(1.0), Jump(0, 0)], "needs at least one waypoint"),
    ],
)
def test_load_refuses_what_cannot_work_and_keeps_the_mission(items: list[DrivenItem], match: str) -> None:
    mission = Mission()
    mission.load(steps(A, B))
    with pytest.raises(ParameterError, match=match):
        mission.load(steps(*items))
    assert mission.items == (A, B)


def test_the_walk_stays_bounded_even_on_a_loop_load_would_refuse() -> None:
    # load refuses an idle loop; should one ever get in, a tick must still end: the walk passes at most
    # count + 1 items, then ends the mission COMPLETE instead of spinning the control tick.
    mission = Mission()
    mission.load(steps(A, B))
    mission.items = (A, SLOW, Jump(1, JUMP_FOREVER), Jump(2, JUMP_FOREVER))
    leg = mission.set_current(1)  # returns: a spinning walk would never get to the asserts below
    assert leg.target is None and mission.state is MissionState.COMPLETE
    assert len(leg.speed_changes) + len(leg.jumps) <= len(mission.items) + 1
