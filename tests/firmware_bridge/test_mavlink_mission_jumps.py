"""The mission server's jump (MAV_CMD_DO_JUMP) and delay (MAV_CMD_NAV_DELAY) items against a pymavlink ground
station over the lockstep memory pipe: accepted, numbered as uploaded, handed over as the rover drives them,
downloaded back field for field, and each bad parameter, and each jump looping without an item that moves
the rover, refused naming the param."""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_mission import MissionAccepted
from firmware_bridge.mission_delay import Delay
from firmware_bridge.mission_hold import PlacedWaypoint
from firmware_bridge.mission_jump import JUMP_FOREVER, Jump
from firmware_bridge.mission_speed import SpeedChange
from tests.firmware_bridge.ground_station import MISSION, ROVER, change_speed, do_jump, nav_delay, waypoint
from tests.firmware_bridge.test_mavlink_mission import PLAN, Rig, place

INVALID_PARAM1 = mavlink2.MAV_MISSION_INVALID_PARAM1
INVALID_PARAM2 = mavlink2.MAV_MISSION_INVALID_PARAM2


def laps() -> list[Any]:
    """A lap of two waypoints driven three times (jumped back twice), a delay, then a third waypoint."""
    (lat0, lon0), (lat1, lon1), (lat2, lon2) = PLAN
    return [
        waypoint(0, lat0, lon0),
        waypoint(1, lat1, lon1),
        do_jump(2, 0, 2),
        nav_delay(3, 5.0),
        waypoint(4, lat2, lon2),
    ]


def test_a_jump_and_a_delay_are_accepted_as_the_rover_drives_them() -> None:
    rig = Rig()
    assert rig.upload(laps()).type == mavlink2.MAV_MISSION_ACCEPTED
    (change,) = rig.changes
    assert isinstance(change, MissionAccepted)
    placed = [place(lat, lon) for lat, lon in PLAN]
    assert change.steps == (
        PlacedWaypoint(*placed[0], 0.0),
        PlacedWaypoint(*placed[1], 0.0),
        Jump(0, 2),
        Delay(5.0),
        PlacedWaypoint(*placed[2], 0.0),
    )
    assert [i.command for i in rig.server.items] == [16, 16, 177, 93, 16]
    assert rig.link.counters.missions_accepted == 1 and rig.link.counters.mission_refused == 0


def test_they_download_field_for_field() -> None:
    rig = Rig()
    rig.upload(laps())
    rig.exchange(mavlink2.MAVLink_mission_request_list_message(*ROVER, MISSION))
    names = ("seq", "frame", "command", "autocontinue", "x", "y", "z", "param1", "param2", "param3", "param4")
    for seq, original in enumerate(laps()):
        (item,) = rig.exchange(mavlink2.MAVLink_mission_request_int_message(*ROVER, seq, MISSION))
        for name in names:
            mine, theirs = getattr(item, name), getattr(original, name)
            assert mine == theirs or (math.isnan(mine) and math.isnan(theirs)), (seq, name)


@pytest.mark.parametrize(
    ("middle", "taken"),
    [
        # A jump forward over a speed change; one for ever back to a waypoint; one that never jumps (0),
        # even to itself.
        pytest.param([do_jump(1, 3, 1), change_speed(2, 0.5)], Jump(3, 1), id="forward"),
        pytest.param([do_jump(1, 0, -1)], Jump(0, JUMP_FOREVER), id="for-ever-back-to-a-waypoint"),
        pytest.param([do_jump(1, 1, 0)], Jump(1, 0), id="count-0-never-jumps"),
    ],
)
def test_jumps_that_can_work_are_accepted(middle: list[Any], taken: Jump) -> None:
    rig = Rig()
    plan = [waypoint(0, *PLAN[0]), *middle, waypoint(len(middle) + 1, *PLAN[1])]
    assert rig.upload(plan).type == mavlink2.MAV_MISSION_ACCEPTED
    change = rig.changes[-1]
    assert isinstance(change, MissionAccepted) and change.steps[1] == taken


def _jump_refusal(param1: float, param2: float, reason: str, name: str) -> Any:
    result = INVALID_PARAM1 if "(param1)" in reason else INVALID_PARAM2
    return pytest.param([do_jump(1, param1, param2)], result, reason, id=name)


@pytest.mark.parametrize(
    ("tail", "result", "reason"),
    [
        _jump_refusal(
            math.nan, 1, "item 1: DO_JUMP target (param1) nan is not an item of the mission", "nan"
        ),
        _jump_refusal(0.5, 1, "item 1: DO_JUMP target (param1) 0.5 is not an item of the mission", "half"),
        _jump_refusal(-1, 1, "item 1: DO_JUMP target (param1) -1.0 is not an item", "negative"),
        _jump_refusal(3, 1, "target (param1) 3.0 is not an item of the mission: a whole number 0..2", "past"),
        _jump_refusal(0, math.nan, "item 1: DO_JUMP repeat count (param2) nan is not a count", "count-nan"),
        _jump_refusal(0, 1.5, "item 1: DO_JUMP repeat count (param2) 1.5 is not a count", "count-half"),
        _jump_refusal(0, -2, "item 1: DO_JUMP repeat count (param2) -2.0 is not a count", "count-minus-2"),
        _jump_refusal(0, math.inf, "repeat count (param2) inf is not a count", "count-inf"),
        # Loops the mission would go round without moving the rover, refused at the upload's last item.
        pytest.param(
            [do_jump(1, 1, 3)],
            INVALID_PARAM1,
            "item 1: DO_JUMP target (param1) 1: the loop from item 1 back to item 1 has no waypoint, loiter "
            "or return to launch",
            id="to-itself",
        ),
        pytest.param(
            [do_jump(1, 2, -1), do_jump(2, 1, -1)],
            INVALID_PARAM1,
            "item 2: DO_JUMP target (param1) 1: the loop from item 1 back to item 2 has no waypoint",
            id="two-jumps-to-each-other",
        ),
        pytest.param(
            [change_speed(1, 0.5), nav_delay(2, 3.0), do_jump(3, 1, 2)],
            INVALID_PARAM1,
            "item 3: DO_JUMP target (param1) 1: the loop from item 1 back to item 3 has no waypoint",
            id="back-over-a-speed-change-and-a-delay",
        ),
    ],
)
def test_a_jump_that_cannot_work_is_refused_naming_the_param(
    tail: list[Any], result: int, reason: str
) -> None:
    rig = Rig()
    plan = [waypoint(0, *PLAN[0]), *tail, waypoint(len(tail) + 1, *PLAN[1])]
    answer = rig.upload(plan)
    text = "".join(m.text for m in rig.gcs.of_type("STATUSTEXT"))
    assert answer.type == result and reason in text, text
    assert rig.server.items == () and rig.link.counters.mission_refused == 1


@pytest.mark.parametrize(
    ("item", "reason"),
    [
        pytest.param(
            nav_delay(1, -1.0, 14, 30, 0),
            "item 1: NAV_DELAY delay (param1) -1, until a time of day (params 2-4), is not taken",
            id="time-of-day",
        ),
        *[
            pytest.param(
                nav_delay(1, seconds),
                f"item 1: NAV_DELAY delay (param1) {shown} s is not a delay: 0 to 3600 s",
                id=f"delay-{shown}",
            )
            for seconds, shown in [(math.nan, "nan"), (-2.0, "-2.0"), (math.inf, "inf"), (3601.0, "3601.0")]
        ],
    ],
)
def test_a_bad_delay_is_refused_naming_the_param(item: Any, reason: str) -> None:
    rig = Rig()
    answer = rig.upload([waypoint(0, *PLAN[0]), item])
    text = "".join(m.text for m in rig.gcs.of_type("STATUSTEXT"))
    assert answer.type == INVALID_PARAM1 and reason in text, text
    assert rig.server.items == ()


def test_jumps_and_delays_alone_have_nowhere_to_drive() -> None:
    rig = Rig()
    answer = rig.upload([nav_delay(0, 1.0), do_jump(1, 0, 0)])
    text = "".join(m.text for m in rig.gcs.of_type("STATUSTEXT"))
    assert answer.type == mavlink2.MAV_MISSION_ERROR and "with no MAV_CMD_NAV_WAYPOINT" in text


def test_a_speed_change_and_a_delay_stay_what_they_were() -> None:
    rig = Rig()
    plan = [change_speed(0, 0.5), nav_delay(1, 0.0), waypoint(2, *PLAN[0])]
    assert rig.upload(plan).type == mavlink2.MAV_MISSION_ACCEPTED
    change = rig.changes[-1]
    assert isinstance(change, MissionAccepted)
    assert change.steps[:2] == (SpeedChange(0.5), Delay(0.0))
