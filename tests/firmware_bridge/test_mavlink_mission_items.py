"""The mission server's return-to-launch and loiter items against a pymavlink ground station over the
lockstep memory pipe: accepted, numbered as uploaded, driven as the rover drives them (``steps``),
downloaded back field for field, and each bad parameter refused naming it."""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_commands import StartRequest
from firmware_bridge.mavlink_home import ReturnToLaunch
from firmware_bridge.mavlink_mission import MissionAccepted
from firmware_bridge.mission_hold import HOLD_UNLIMITED, MAX_HOLD_S, PlacedWaypoint
from firmware_bridge.mission_speed import SpeedChange
from tests.firmware_bridge.ground_station import (
    MISSION,
    ROVER,
    change_speed,
    command_long,
    loiter,
    return_to_launch,
    waypoint,
)
from tests.firmware_bridge.test_mavlink_mission import PLAN, Rig, count, place


def home_bound() -> list[Any]:
    """A plan as QGroundControl and Mission Planner end one: a waypoint, a timed loiter, a loiter without
    end, and "Return to launch"."""
    (lat0, lon0), (lat1, lon1), (lat2, lon2) = PLAN
    return [
        waypoint(0, lat0, lon0),
        loiter(1, lat1, lon1, 30.0),
        loiter(2, lat2, lon2),
        return_to_launch(3),
    ]


def test_loiters_and_a_return_to_launch_are_accepted_as_the_rover_drives_them() -> None:
    rig = Rig()
    assert rig.upload(home_bound()).type == mavlink2.MAV_MISSION_ACCEPTED
    (change,) = rig.changes
    assert isinstance(change, MissionAccepted)
    placed = [place(lat, lon) for lat, lon in PLAN]
    assert change.steps == (
        PlacedWaypoint(*placed[0], 0.0),
        PlacedWaypoint(*placed[1], 30.0),  # the loiter time: a hold, as a waypoint's
        PlacedWaypoint(*placed[2], HOLD_UNLIMITED),
        ReturnToLaunch(),
    )
    assert [i.command for i in rig.server.items] == [16, 19, 17, 20]
    assert rig.link.counters.missions_accepted == 1 and rig.link.counters.mission_refused == 0


def test_they_download_field_for_field() -> None:
    rig = Rig()
    rig.upload(home_bound())
    rig.exchange(mavlink2.MAVLink_mission_request_list_message(*ROVER, MISSION))
    sent = home_bound()
    names = ("seq", "frame", "command", "autocontinue", "x", "y", "z", "param1", "param2", "param3", "param4")
    for seq, original in enumerate(sent):
        (item,) = rig.exchange(mavlink2.MAVLink_mission_request_int_message(*ROVER, seq, MISSION))
        for name in names:
            mine, theirs = getattr(item, name), getattr(original, name)
            assert mine == theirs or (math.isnan(mine) and math.isnan(theirs)), (seq, name)


def test_a_return_to_launch_is_a_mission_without_any_waypoint() -> None:
    rig = Rig()
    plan = [change_speed(0, 0.5), return_to_launch(1, frame=mavlink2.MAV_FRAME_GLOBAL_INT)]  # any frame
    assert rig.upload(plan).type == mavlink2.MAV_MISSION_ACCEPTED
    assert rig.changes[-1] == MissionAccepted(
        rig.server.items, (SpeedChange(0.5), ReturnToLaunch()), 255, 190
    )


@pytest.mark.parametrize(
    ("item", "result", "reason"),
    [
        *[
            pytest.param(
                loiter(0, 47.0, 8.0, seconds),
                mavlink2.MAV_MISSION_INVALID_PARAM1,
                f"item 0: MAV_CMD_NAV_LOITER_TIME loiter time (param1) {shown} s is not a hold: 0 to 3600 s "
                "(0: none)",
                id=f"loiter-time-{shown}",
            )
            # NaN refused: a loiter time left unset is no loiter (a waypoint's NaN hold is none).
            for seconds, shown in [
                (-1.0, "-1.0"),
                (math.inf, "inf"),
                (math.nan, "nan"),
                (MAX_HOLD_S + 1, "3601.0"),
            ]
        ],
        pytest.param(
            loiter(0, 91.0, 8.0),
            mavlink2.MAV_MISSION_INVALID_PARAM5_X,
            "item 0: latitude 910000000 x 1e-7 is out of range",
            id="loiter-latitude",
        ),
        pytest.param(
            loiter(0, 47.0, 181.0, 5.0),
            mavlink2.MAV_MISSION_INVALID_PARAM6_Y,
            "item 0: longitude 1810000000 x 1e-7 is out of range",
            id="loiter-longitude",
        ),
        pytest.param(
            loiter(0, 47.002, 8.0),
            mavlink2.MAV_MISSION_DENIED,
            "item 0: waypoint at latitude 47.0020 is outside the geofence",
            id="loiter-outside-the-fence",
        ),
    ],
)
def test_a_bad_loiter_is_refused_naming_the_param(item: Any, result: int, reason: str) -> None:
    rig = Rig()
    received = rig.exchange(count(2))
    rig.gcs.answer([item], received)
    answer, text = rig.refusal(rig.step())
    assert answer == result and reason in text, text
    assert rig.server.items == () and rig.link.counters.mission_refused == 1


def test_a_loiter_in_a_local_frame_is_refused() -> None:
    rig = Rig()
    item = loiter(0, 47.0, 8.0, 5.0)
    item.frame = mavlink2.MAV_FRAME_LOCAL_NED
    received = rig.exchange(count(1))
    rig.gcs.answer([item], received)
    answer, text = rig.refusal(rig.step())
    assert answer == mavlink2.MAV_MISSION_UNSUPPORTED_FRAME and "frame 1 (MAV_FRAME_LOCAL_NED)" in text


def test_a_home_command_handed_to_the_server_is_never_read_as_a_mission_start() -> None:
    rig = Rig()
    rig.upload(home_bound())
    (answer,) = [
        m
        for m in rig.exchange(command_long(mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH))
        if m.get_type() == "COMMAND_ACK"
    ]
    assert answer.result == mavlink2.MAV_RESULT_UNSUPPORTED
    assert not any(isinstance(change, StartRequest) for change in rig.changes)
