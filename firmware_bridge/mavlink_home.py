"""Home over MAVLink: the HOME_POSITION message and the commands about home, as the rover reads them
(https://mavlink.io/en/messages/common.html#HOME_POSITION, #MAV_CMD_DO_SET_HOME,
#MAV_CMD_NAV_RETURN_TO_LAUNCH).

Defined here, below both the link (``firmware_bridge.mavlink_link``), which routes these commands, and the
onboard stack (``navigator.onboard_home``), which keeps home and answers them: ``navigator`` imports
``firmware_bridge``, never the other way round (docs/ARCHITECTURE.md).

The commands (COMMAND_LONG or COMMAND_INT), judged here for what their parameters say; whether the rover
can do it (a home yet, a datum, the geofence) is the onboard stack's to say:

* MAV_CMD_REQUEST_MESSAGE with param1 = 242 (HOME_POSITION), and the deprecated MAV_CMD_GET_HOME_POSITION:
  ``HomeAsked``. A REQUEST_MESSAGE for any other message is not routed here (the link refuses it).
* MAV_CMD_DO_SET_HOME: param1 = 1, the rover's current position; 0, the given latitude and longitude
  (COMMAND_LONG: param5 / param6 in degrees; COMMAND_INT: x / y in degrees x 1e7, in a global frame); as
  ArduPilot does, a given position of 0, 0 means the current one. Any other param1 (the spec: "values not
  equal to 0 or 1 are invalid"), a position out of range or not finite, a frame not global: DENIED naming
  it. ``SetHomeRequest``. The altitude (param7) is not used: home is placed as goals are, on the ground
  the rover drives.
* MAV_CMD_NAV_RETURN_TO_LAUNCH (no parameters): ``ReturnRequested``: drive home, as a single goal.

As a mission item (``firmware_bridge.mavlink_mission``) MAV_CMD_NAV_RETURN_TO_LAUNCH is ``ReturnToLaunch``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_commands import GLOBAL_FRAMES

HOME_POSITION_ID = mavlink2.MAVLINK_MSG_ID_HOME_POSITION  # 242
# The commands this module reads (MAV_CMD_REQUEST_MESSAGE only for HOME_POSITION: is_home_command).
_HOME_COMMANDS = frozenset(
    {
        mavlink2.MAV_CMD_GET_HOME_POSITION,
        mavlink2.MAV_CMD_DO_SET_HOME,
        mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH,
    }
)
_COMMANDS = frozenset({"COMMAND_LONG", "COMMAND_INT"})
# HOME_POSITION.q: "all NaN if an accurate quaternion for both heading and surface slope cannot be
# supplied"; the rover measures neither at home.
_NO_SURFACE = (math.nan, math.nan, math.nan, math.nan)
_DEGREES_E7 = 1e-7


@dataclass(frozen=True)
class Home:
    """The position the rover returns to: WGS84 degrees and metres (altitude above mean sea level), and
    the same point in the local ENU frame (metres from the estimator's datum). ``how``: how it was set,
    for the events (``navigator.onboard_home``)."""

    lat_deg: float
    lon_deg: float
    alt_m: float
    x: float
    y: float
    z: float
    how: str


@dataclass(frozen=True)
class ReturnToLaunch:
    """A MAV_CMD_NAV_RETURN_TO_LAUNCH mission item as the rover drives it: to home as it is when the
    mission comes to the item; reached, the mission goes on to its next item (complete when it was the
    last), as ArduPilot Rover's Auto mode goes on after its RTL sub-mode reaches home."""


class HomeAsked(NamedTuple):
    """MAV_CMD_REQUEST_MESSAGE(HOME_POSITION) or MAV_CMD_GET_HOME_POSITION: answer with HOME_POSITION."""


class SetHomeRequest(NamedTuple):
    """MAV_CMD_DO_SET_HOME: home at the current position (``current``), or at ``lat_deg``, ``lon_deg``."""

    current: bool
    lat_deg: float = math.nan
    lon_deg: float = math.nan


class ReturnRequested(NamedTuple):
    """MAV_CMD_NAV_RETURN_TO_LAUNCH as a command: drive home."""


class HomeRefusal(NamedTuple):
    """Why a home command is refused: the MAV_RESULT to answer with and the reason."""

    result: int
    reason: str


HomeCommand = HomeAsked | SetHomeRequest | ReturnRequested


def is_home_command(msg: Any) -> bool:
    """A COMMAND_LONG / COMMAND_INT this module reads (the onboard stack's, not the link's to answer); a
    mission item carrying the same command (a MISSION_ITEM_INT return to launch) is not one."""
    if msg.get_type() not in _COMMANDS:
        return False
    command = msg.command
    if command == mavlink2.MAV_CMD_REQUEST_MESSAGE:
        return bool(msg.param1 == HOME_POSITION_ID)
    return command in _HOME_COMMANDS


def judge_home_command(msg: Any) -> HomeCommand | HomeRefusal:
    """What a home command (``is_home_command``) asks, or why its parameters cannot be taken."""
    command = msg.command
    if command == mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH:
        return ReturnRequested()
    if command != mavlink2.MAV_CMD_DO_SET_HOME:
        return HomeAsked()
    use_current = msg.param1
    if use_current not in (0.0, 1.0):
        return HomeRefusal(
            mavlink2.MAV_RESULT_DENIED,
            f"DO_SET_HOME param1 {use_current}: 1 (the current position) or 0 (the given position)",
        )
    if use_current == 1.0:
        return SetHomeRequest(current=True)
    if msg.get_type() == "COMMAND_INT":
        if msg.frame not in GLOBAL_FRAMES:
            return HomeRefusal(mavlink2.MAV_RESULT_DENIED, f"DO_SET_HOME frame {msg.frame} is not global")
        lat, lon = msg.x * _DEGREES_E7, msg.y * _DEGREES_E7
        lat_field, lon_field = "x", "y"  # COMMAND_INT carries them in x and y, degrees x 1e7
    else:
        lat, lon = msg.param5, msg.param6
        lat_field, lon_field = "param5", "param6"
    if lat == 0.0 and lon == 0.0:
        return SetHomeRequest(current=True)  # ArduPilot's reading of an empty position
    if not (math.isfinite(lat) and -90.0 <= lat <= 90.0):
        return HomeRefusal(
            mavlink2.MAV_RESULT_DENIED, f"DO_SET_HOME latitude ({lat_field}) {lat} is out of range"
        )
    if not (math.isfinite(lon) and -180.0 <= lon <= 180.0):
        return HomeRefusal(
            mavlink2.MAV_RESULT_DENIED, f"DO_SET_HOME longitude ({lon_field}) {lon} is out of range"
        )
    return SetHomeRequest(False, float(lat), float(lon))


def home_position_message(home: Home, time_usec: int) -> Any:
    """HOME_POSITION for ``home``: latitude and longitude in degrees x 1e7, altitude in mm above mean sea
    level, and x, y, z in the local frame as MAVLink gives it, NED (north, east, down: our ENU y, x, -z).
    q all NaN (no surface measured); the approach vector 0 (a rover does not land)."""
    return mavlink2.MAVLink_home_position_message(
        round(home.lat_deg / _DEGREES_E7),
        round(home.lon_deg / _DEGREES_E7),
        round(home.alt_m * 1000.0),
        home.y,
        home.x,
        -home.z,
        _NO_SURFACE,
        0.0,
        0.0,
        0.0,
        time_usec,
    )
