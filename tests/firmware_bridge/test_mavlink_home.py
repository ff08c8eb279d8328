"""Home commands as the bridge reads them (``firmware_bridge.mavlink_home``): what each asks, each bad
parameter refused naming it, HOME_POSITION's fields, and the link handing them to the onboard stack
(addressed to our component by its id, as mission messages)."""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_home import (
    Home,
    HomeAsked,
    HomeRefusal,
    ReturnRequested,
    SetHomeRequest,
    home_position_message,
    is_home_command,
    judge_home_command,
)
from firmware_bridge.mavlink_link import MavlinkLink
from firmware_bridge.mavlink_mission import MissionMessage
from firmware_bridge.mavlink_transport import memory_pipe_pair
from logs.clock import SimClock
from logs.sink import MemorySink
from tests.firmware_bridge.ground_station import GroundStation, command_long, return_to_launch

HOME_POSITION = float(mavlink2.MAVLINK_MSG_ID_HOME_POSITION)


def set_home_int(use_current: float, lat: float, lon: float, frame: int = mavlink2.MAV_FRAME_GLOBAL) -> Any:
    return mavlink2.MAVLink_command_int_message(
        1, 191, frame, mavlink2.MAV_CMD_DO_SET_HOME, 0, 0, use_current, 0, 0, 0,
        round(lat * 1e7), round(lon * 1e7), 400.0,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("msg", "expected"),
    [
        (command_long(mavlink2.MAV_CMD_REQUEST_MESSAGE, HOME_POSITION), HomeAsked()),
        (command_long(mavlink2.MAV_CMD_GET_HOME_POSITION), HomeAsked()),
        (command_long(mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH), ReturnRequested()),
        (command_long(mavlink2.MAV_CMD_DO_SET_HOME, 1.0), SetHomeRequest(current=True)),
        (
            command_long(mavlink2.MAV_CMD_DO_SET_HOME, 0.0, 0, 0, 0, 47.0001, 8.0002, 400.0),
            SetHomeRequest(False, 47.0001, 8.0002),
        ),
        (set_home_int(0.0, 47.0001, 8.0002), SetHomeRequest(False, 47.0001, 8.0002)),
        # ArduPilot reads a given position of 0, 0 as "the current one".
        (command_long(mavlink2.MAV_CMD_DO_SET_HOME, 0.0), SetHomeRequest(current=True)),
    ],
)
def test_each_home_command_says_what_it_asks(msg: Any, expected: Any) -> None:
    assert is_home_command(msg)
    verdict = judge_home_command(msg)
    if isinstance(expected, SetHomeRequest) and not expected.current:
        assert isinstance(verdict, SetHomeRequest) and not verdict.current
        assert (verdict.lat_deg, verdict.lon_deg) == pytest.approx((expected.lat_deg, expected.lon_deg))
    else:
        assert verdict == expected


def test_other_commands_are_not_home_commands() -> None:
    assert not is_home_command(command_long(mavlink2.MAV_CMD_REQUEST_MESSAGE, 33.0))  # GLOBAL_POSITION_INT
    assert not is_home_command(command_long(mavlink2.MAV_CMD_MISSION_START))
    assert not is_home_command(mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))
    assert not is_home_command(return_to_launch(0))  # the mission item, not the command


@pytest.mark.parametrize(
    ("msg", "reason"),
    [
        (
            command_long(mavlink2.MAV_CMD_DO_SET_HOME, 2.0),
            "DO_SET_HOME param1 2.0: 1 (the current position) or 0",
        ),
        (command_long(mavlink2.MAV_CMD_DO_SET_HOME, math.nan), "DO_SET_HOME param1 nan"),
        (
            command_long(mavlink2.MAV_CMD_DO_SET_HOME, 0.0, 0, 0, 0, 91.0, 8.0),
            "DO_SET_HOME latitude (param5) 91.0 is out of range",
        ),
        (
            command_long(mavlink2.MAV_CMD_DO_SET_HOME, 0.0, 0, 0, 0, 47.0, math.inf),
            "DO_SET_HOME longitude (param6) inf is out of range",
        ),
        (set_home_int(0.0, 47.0, 8.0, mavlink2.MAV_FRAME_LOCAL_NED), "DO_SET_HOME frame 1 is not global"),
        # COMMAND_INT carries the position in x and y: the reason names those fields.
        (set_home_int(0.0, 91.0, 8.0), "DO_SET_HOME latitude (x) 91.0 is out of range"),
        (set_home_int(0.0, 47.0, 181.0), "DO_SET_HOME longitude (y) 181.0 is out of range"),
    ],
)
def test_a_bad_set_home_is_denied_naming_the_param(msg: Any, reason: str) -> None:
    verdict = judge_home_command(msg)
    assert isinstance(verdict, HomeRefusal)
    assert verdict.result == mavlink2.MAV_RESULT_DENIED and reason in verdict.reason


def test_home_position_gives_the_local_position_in_ned() -> None:
    home = Home(47.0001, 8.0002, 402.5, x=15.2, y=11.1, z=2.5, how="test")
    msg = home_position_message(home, 1_500_000)
    assert (msg.latitude, msg.longitude, msg.altitude) == (470001000, 80002000, 402500)
    assert (msg.x, msg.y, msg.z) == pytest.approx((11.1, 15.2, -2.5))  # north, east, down
    assert all(math.isnan(q) for q in msg.q) and msg.time_usec == 1_500_000


def test_the_link_hands_home_commands_addressed_to_our_component_to_the_stack() -> None:
    companion, ground = memory_pipe_pair()
    link = MavlinkLink(companion, SimClock(5), MemorySink(), system_id=1, component_id=191)
    station = GroundStation(ground)
    station.send(command_long(mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH))
    station.send(command_long(mavlink2.MAV_CMD_REQUEST_MESSAGE, HOME_POSITION))
    (rtl, asked) = link.poll()
    assert isinstance(rtl, MissionMessage) and rtl.msg.command == mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH
    assert isinstance(asked, MissionMessage) and asked.msg.param1 == HOME_POSITION
    assert station.receive() == []  # answered by the stack, not the link
    # Component-broadcast, on the autopilot's link: the autopilot's home, not ours; nobody here answers.
    station.send(command_long(mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH, target=(1, 0)))
    assert link.poll() == [] and station.receive() == []
    assert link.counters.commands_rejected == 0
