"""The rover's home: where it returns to (MAV_CMD_NAV_RETURN_TO_LAUNCH, as a command or a mission item),
and the answers to a ground station's home commands (``firmware_bridge.mavlink_home``).

Home is where the rover stood when its position estimate first became healthy (``PoseEstimate.healthy``:
a datum, the heading known, position and heading tight), taken from the estimate, never from a raw fix:
ArduPilot sets home from its EKF's position (``Rover::set_home_to_current_location``), and a raw first
fix may be a glitch the filter goes on to throw out. The rover does not drive before the estimate is
healthy (the start-up check), so that is where it stood. One correction while home is still unused: when
the estimator re-anchors its position on GPS (``Estimator.last_gps_reset``: GPS disagreed with the
estimate for ``gps_reset_after_s``) and no fix agreed with the estimate between home being taken and the
disagreement, the estimate home came from was off by the same jump (a first fix 25 m off that started the
filter there), and home moves by it. A re-anchoring after fixes had agreed is later drift, not home's:
home stays. A re-anchoring is itself an agreement (``GpsReset.agreed_until_ns``), so home moves at most
once this way: a second long disagreement right after the first is a glitch after home was put right.
Once used (driven to, or moved by DO_SET_HOME), home is fixed: only DO_SET_HOME moves it. A ground station
asking where home is (HOME_POSITION) does not fix it: many ask on connect, and that would keep a glitched
first fix home for good; it is told home as it is then, and the correction, should it come, as a move.

MAV_CMD_DO_SET_HOME moves it: to the current position (the pose estimate's) or to a given latitude and
longitude, placed as goals are; refused outside the geofence (home is where RTL drives) and before the
rover knows where it is. Home is on the ground plane at the datum's altitude (ENU z 0), as goals are.

Every home told is a ``home`` event on ``safety/events``, so a trial's recording says where home was
whenever home mattered in it, and a HOME_POSITION to the ground stations that follow the mission
(``listeners``; never the autopilot's link, whose home is its own), as ArduPilot sends HOME_POSITION when
home is set or moved: a ground station that did not ask learns where home is now. The one that asked or
moved it has its answer on its own link, once. Where home will be is followed every tick (``observe``,
which records nothing until home has been told); it is first told, with its event, when home is first
needed (a ground station asks for it, moves it, or sends the rover there; a mission comes to a return to
launch), and again as ``home moved to`` when a correction moves it after it was told and before it was
fixed. A trial that never uses home records what it always did (the default trial's recording stays
byte-identical).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

from pymavlink.dialects.v20 import common as mavlink2

from estimator.estimator import Estimator, GpsReset
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
from firmware_bridge.mavlink_mission import MissionLink, refuse_command
from logs.clock import Clock, seconds
from navigator.safety import EventSink

_NS_PER_US = 1000
_NO_HOME_YET = "no home yet (the position estimate has not been healthy yet)"


class _Spot(NamedTuple):
    """Where home will be, until it is first needed: ENU metres, the estimate's time, and how it came."""

    t_ns: int
    x: float
    y: float
    how: str


class HomeKeeper:
    """Home and the home commands. ``placed`` turns a latitude and longitude into ENU metres the way
    goals are placed (None before the datum is known); ``outside_fence`` says whether an ENU point is
    outside ``[safety] fence``; ``event`` publishes a ``safety/events`` message; ``listeners``: the links
    each new home is told on (none by default)."""

    def __init__(
        self,
        clock: Clock,
        estimator: Estimator,
        placed: Callable[[float, float], tuple[float, float] | None],
        outside_fence: Callable[[float, float], bool],
        event: EventSink,
        listeners: Callable[[], Sequence[MissionLink]] = tuple,
    ) -> None:
        self._clock = clock
        self._listeners = listeners
        self._estimator = estimator
        self._placed = placed
        self._outside_fence = outside_fence
        self._event = event
        self._home: Home | None = None  # home fixed: driven to, or set by DO_SET_HOME
        self._told: Home | None = None  # the home last told (event, HOME_POSITION), fixed or not
        self._spot: _Spot | None = None  # where home will be, while it is unused
        self._reset_seen: GpsReset | None = None  # the estimator's last re-anchoring, as last looked at

    def observe(self) -> None:
        """Every tick, while home is unused: the estimate's position at its first healthy tick becomes
        where home will be, moved by a re-anchoring on GPS that shows it was off (the module's note).
        Records nothing, unless home was told before it was fixed: then the move is told too."""
        if self._home is not None:
            return
        estimator = self._estimator
        reset = estimator.last_gps_reset
        spot = self._spot
        if spot is None:
            pose = estimator.pose()
            if pose is None or not pose.healthy or estimator.datum is None:
                return
            how = f"the rover's position estimate at {seconds(pose.t_ns):.2f} s, its first healthy one"
            self._spot, self._reset_seen = _Spot(pose.t_ns, pose.x, pose.y, how), reset
            return
        if reset is None or reset is self._reset_seen:
            return
        self._reset_seen = reset
        if reset.agreed_until_ns > spot.t_ns:
            # A fix (or a re-anchoring) agreed with the estimate after home was taken: later drift, not
            # home's error.
            return
        jump = math.hypot(reset.east_m, reset.north_m)
        self._spot = _Spot(
            spot.t_ns,
            spot.x + reset.east_m,
            spot.y + reset.north_m,
            f"{spot.how}, moved {jump:.2f} m by the estimator's re-anchoring on GPS at "
            f"{seconds(reset.t_ns):.2f} s",
        )
        if self._told is not None:
            # A ground station was told the home before the correction (it asked): told again, as a move.
            moved = self._from_spot()
            if moved is not None:
                self._tell(moved)

    def home(self) -> Home | None:
        """Home, fixed (to be driven to), or None before the position estimate has been healthy (and no
        DO_SET_HOME). The estimate's home is fixed here, on first need, with its ``home`` event and
        HOME_POSITION to the listeners unless it was told already as it is (the module's note)."""
        home = self._home
        if home is not None:
            return home
        home = self.where()
        if home is not None:
            self._home = home
        return home

    def where(self, asked_on: MissionLink | None = None) -> Home | None:
        """Home as it is now, not fixed (a HOME_POSITION request's answer): a correction may still move
        it. Told (its ``home`` event, HOME_POSITION to the listeners but ``asked_on``, where the caller
        answers with it) unless told already as it is; None before the estimate has been healthy."""
        home = self._home
        if home is not None:
            return home
        self.observe()
        home = self._from_spot()
        if home is not None and home != self._told:
            self._tell(home, asked_on=asked_on)
        return home

    def _from_spot(self) -> Home | None:
        """Where home will be (the estimate's), as a ``Home``; None before there is one."""
        spot, datum = self._spot, self._estimator.datum
        if spot is None or datum is None:
            return None
        lat, lon, alt = to_geodetic(datum, spot.x, spot.y, 0.0)
        return Home(lat, lon, alt, spot.x, spot.y, 0.0, spot.how)

    def return_target(self) -> Home | HomeRefusal:
        """Where a return to launch drives (home), or why it cannot: no home yet, home outside the
        geofence (the rover's own start may be: DO_SET_HOME refuses any other there)."""
        home = self.home()
        if home is None:
            return HomeRefusal(mavlink2.MAV_RESULT_TEMPORARILY_REJECTED, _NO_HOME_YET)
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
            home = self.where(asked_on=link)
            refusal = HomeRefusal(mavlink2.MAV_RESULT_TEMPORARILY_REJECTED, _NO_HOME_YET)
            answer = home if home is not None else refusal
        else:
            answer = self._judge_set(verdict, msg)
        if isinstance(answer, HomeRefusal):
            refuse_command(link, msg, answer.result, answer.reason)
            return None
        sysid, compid = msg.get_srcSystem(), msg.get_srcComponent()
        link.send(
            mavlink2.MAVLink_command_ack_message(
                msg.command, mavlink2.MAV_RESULT_ACCEPTED, 0, 0, sysid, compid
            )
        )
        if isinstance(verdict, SetHomeRequest):
            self._set(answer, f" by {sysid}/{compid}", asked_on=link)
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

    def _set(self, home: Home, by: str = "", *, asked_on: MissionLink | None = None) -> None:
        """Home is ``home`` now, fixed (DO_SET_HOME), and told (``_tell``)."""
        self._tell(home, by, asked_on=asked_on)
        self._home = home

    def _tell(self, home: Home, by: str = "", *, asked_on: MissionLink | None = None) -> None:
        """Home told as ``home``: its ``home`` event, and HOME_POSITION to each listener but ``asked_on``."""
        moved = self._told is not None
        self._told = home
        verb = "home moved to" if moved else "home at"
        self._event(
            "home",
            "info",
            f"{verb} ({home.lat_deg:.7f}, {home.lon_deg:.7f}, {home.alt_m:.2f} m), ENU ({home.x:.2f}, "
            f"{home.y:.2f}, {home.z:.2f}): {home.how}{by}",
        )
        told = None
        for listener in self._listeners():
            if listener is not asked_on:
                told = told or home_position_message(home, self._clock.now_ns() // _NS_PER_US)
                listener.send(told)
