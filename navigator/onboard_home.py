"""The rover's home: where it returns to (MAV_CMD_NAV_RETURN_TO_LAUNCH, as a command or a mission item),
and the answers to a ground station's home commands (``firmware_bridge.mavlink_home``).

Home is where the rover stood at its first GPS fix, as ArduPilot sets home: the fix that initialised the
estimator (``Estimator.first_fix``: its latitude, longitude and altitude, and the same point in ENU; with
a datum from that fix, ENU (0, 0, 0)). MAV_CMD_DO_SET_HOME moves it: to the current position (the pose
estimate's, on the ground plane at the datum's altitude) or to a given latitude and longitude, placed as
goals are; refused outside the geofence (home is where RTL drives) and before the rover knows where it is.

Every home is a ``home`` event on ``safety/events``, so a trial's recording says where home was whenever
home mattered in it. The first-fix home is taken, and its event published, when home is first needed (a
ground station asks for it, moves it, or sends the rover there; a mission comes to a return to launch), not
at the fix: a trial that never uses home records what it always did (the default trial's recording stays
byte-identical), and its first accepted fix on ``sensors/gps`` is its home all the same.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from pymavlink.dialects.v20 import common as mavlink2

from estimator.estimator import Estimator
from estimator.geodesy import to_geodetic
from firmware_bridge.mavlink_home import (
    Home,
    HomeAsked,
    HomeRefusal,
    ReturnRequested,
    SetHomeRequest,
    home_position_message,
    judge_home_command,
)
from firmware_bridge.mavlink_mission import MissionLink
from logs.clock import Clock, seconds
from navigator.safety import EventSink

_log = logging.getLogger(__name__)

_NS_PER_US = 1000


class HomeKeeper:
    """Home and the home commands. ``placed`` turns a latitude and longitude into ENU metres the way
    goals are placed (None before the datum is known); ``outside_fence`` says whether an ENU point is
    outside ``[safety] fence``; ``event`` publishes a ``safety/events`` message."""

    def __init__(
        self,
        clock: Clock,
        estimator: Estimator,
        placed: Callable[[float, float], tuple[float, float] | None],
        outside_fence: Callable[[float, float], bool],
        event: EventSink,
    ) -> None:
        self._clock = clock
        self._estimator = estimator
        self._placed = placed
        self._outside_fence = outside_fence
        self._event = event
        self._home: Home | None = None

    def home(self) -> Home | None:
        """Home, or None before the first GPS fix (and no DO_SET_HOME). The first-fix home is taken here,
        on first need, with its ``home`` event (see the module's note)."""
        home = self._home
        if home is not None:
            return home
        fix = self._estimator.first_fix
        if fix is None:
            return None
        how = f"where the rover stood at its first GPS fix ({seconds(fix.t_ns):.2f} s)"
        home = Home(fix.lat_deg, fix.lon_deg, fix.alt_m, fix.east_m, fix.north_m, fix.up_m, how)
        self._set(home)
        return home

    def return_target(self) -> Home | HomeRefusal:
        """Where a return to launch drives (home), or why it cannot: no home yet, home outside the
        geofence (one set at the first fix may be: DO_SET_HOME refuses any other there)."""
        home = self.home()
        if home is None:
            return HomeRefusal(mavlink2.MAV_RESULT_TEMPORARILY_REJECTED, "no home yet (no GPS fix)")
        if self._outside_fence(home.x, home.y):
            return HomeRefusal(
                mavlink2.MAV_RESULT_DENIED, f"home ({home.x:.2f}, {home.y:.2f}) is outside the geofence"
            )
        return home

    def take(self, link: MissionLink, msg: Any) -> Home | None:
        """A home command (``is_home_command``) addressed to us, answered on ``link`` (COMMAND_ACK; a
        refusal also a STATUSTEXT ``refused: ...``, counted in ``commands_rejected``; HOME_POSITION when
        asked and after a DO_SET_HOME). Returns home for a MAV_CMD_NAV_RETURN_TO_LAUNCH accepted: the
        caller drives there."""
        verdict = judge_home_command(msg)
        answer: Home | HomeRefusal
        if isinstance(verdict, HomeRefusal):
            answer = verdict
        elif isinstance(verdict, ReturnRequested):
            answer = self.return_target()
        elif isinstance(verdict, HomeAsked):
            home = self.home()
            answer = (
                home
                if home is not None
                else HomeRefusal(mavlink2.MAV_RESULT_TEMPORARILY_REJECTED, "no home yet (no GPS fix)")
            )
        else:
            answer = self._judge_set(verdict, msg)
        sysid, compid = msg.get_srcSystem(), msg.get_srcComponent()
        if isinstance(answer, HomeRefusal):
            link.send(mavlink2.MAVLink_command_ack_message(msg.command, answer.result, 0, 0, sysid, compid))
            link.counters.commands_rejected += 1
            _log.warning(
                "refused %s %d from %d/%d: %s", msg.get_type(), msg.command, sysid, compid, answer.reason
            )
            link.send_status_text(f"refused: {answer.reason}", mavlink2.MAV_SEVERITY_WARNING)
            return None
        link.send(
            mavlink2.MAVLink_command_ack_message(
                msg.command, mavlink2.MAV_RESULT_ACCEPTED, 0, 0, sysid, compid
            )
        )
        if isinstance(verdict, SetHomeRequest):
            self._set(answer, f" by {sysid}/{compid}")
        if not isinstance(verdict, ReturnRequested):
            link.send(home_position_message(answer, self._clock.now_ns() // _NS_PER_US))
            return None
        return answer

    def _judge_set(self, request: SetHomeRequest, msg: Any) -> Home | HomeRefusal:
        """The home a DO_SET_HOME asks for, or why not: the rover's position unknown, no datum yet, the
        place outside the geofence."""
        datum = self._estimator.datum
        if request.current:
            pose = self._estimator.pose()
            if datum is None or pose is None or not pose.healthy:
                return HomeRefusal(
                    mavlink2.MAV_RESULT_TEMPORARILY_REJECTED,
                    "DO_SET_HOME: the rover's position is not known yet",
                )
            x, y = pose.x, pose.y
            lat, lon, alt = to_geodetic(datum, x, y, 0.0)
            how = f"the current position (DO_SET_HOME from {msg.get_type()})"
        else:
            placed = self._placed(request.lat_deg, request.lon_deg)
            if datum is None or placed is None:
                return HomeRefusal(
                    mavlink2.MAV_RESULT_TEMPORARILY_REJECTED, "DO_SET_HOME: no ENU datum yet (no GPS fix)"
                )
            x, y = placed
            lat, lon, alt = request.lat_deg, request.lon_deg, datum.alt_m
            how = f"the given position (DO_SET_HOME from {msg.get_type()})"
        if self._outside_fence(x, y):
            return HomeRefusal(
                mavlink2.MAV_RESULT_DENIED, f"DO_SET_HOME: ({x:.2f}, {y:.2f}) is outside the geofence"
            )
        return Home(lat, lon, alt, x, y, 0.0, how)

    def _set(self, home: Home, by: str = "") -> None:
        moved = self._home is not None
        self._home = home
        verb = "home moved to" if moved else "home at"
        self._event(
            "home",
            "info",
            f"{verb} ({home.lat_deg:.7f}, {home.lon_deg:.7f}, {home.alt_m:.2f} m), ENU ({home.x:.2f}, "
            f"{home.y:.2f}, {home.z:.2f}): {home.how}{by}",
        )
