"""Goals and missions for guidance: what the onboard stack is told to drive to, turned into guidance's goal.

A single goal (Zenoh, a ground station's MAVLink goal, ``rover run --goal``) is driven at once and pauses
the mission; a mission (``navigator.mission``), handed over by the trial runner or uploaded by a ground
station with the MAVLink mission protocol (``firmware_bridge.mavlink_mission``, whose server answers the
protocol and hands over what a transfer changes), is driven waypoint by waypoint: an upload at once only
in place of a mission being driven, else on MISSION_START or MISSION_SET_CURRENT. ``MissionDriver`` holds
the mission and its server for the onboard stack (``navigator.onboard``), which calls ``end_tick`` after
each tick's records: the next waypoint becomes the goal at the end of the tick in which guidance reports
ARRIVED.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

from estimator.estimator import Estimator
from estimator.geodesy import to_enu, to_geodetic
from firmware_bridge.mavlink_commands import GoalRequest, StartRequest
from firmware_bridge.mavlink_link import MavlinkLink
from firmware_bridge.mavlink_mission import (
    CurrentRequested,
    MissionAccepted,
    MissionCleared,
    MissionItemRefused,
    MissionMessage,
    MissionServer,
)
from logs.clock import Clock
from navigator.errors import ParameterError
from navigator.fence_shape import Polygon, inside_polygon
from navigator.mission import Mission, MissionState
from navigator.route_guidance import RouteGuidance
from navigator.safety import EventSink

_log = logging.getLogger(__name__)


class MissionDriver:
    """Single goals, missions and the MAVLink mission protocol's changes, as goals for ``RouteGuidance``.

    ``mission`` is the mission in force and its progress, ``server`` the MAVLink mission protocol's server
    (the mission as uploaded, the transfer under way). ``estimator``: its datum places waypoints and goals
    given in latitude and longitude; ``new_goal`` (the safety supervisor's) clears the stuck and stall
    latches on a goal given from outside; ``fence``: ``[safety] fence`` (empty: none), outside which goals
    and waypoints are refused; ``event`` publishes a ``safety/events`` message.
    """

    def __init__(
        self,
        clock: Clock,
        estimator: Estimator,
        guidance: RouteGuidance,
        new_goal: Callable[[], None],
        fence: Polygon,
        event: EventSink,
    ) -> None:
        self._estimator = estimator
        self._guidance = guidance
        self._new_goal = new_goal
        self._fence = fence
        self._event = event
        self.mission = Mission()
        self.server = MissionServer(clock, self._place_waypoint)

    def set_goal(self, x: float, y: float) -> None:
        """A single goal: driven at once, in place of the mission being driven (which is paused: setting
        a current item drives it again). One outside the geofence is refused (``goal_rejected``)."""
        if self._outside_fence(x, y):
            self._event("goal_rejected", "warning", f"goal ({x:.2f}, {y:.2f}) is outside the geofence")
            return
        mission = self.mission
        if mission.pause():
            self._event(
                "mission_paused",
                "info",
                f"a single goal replaced the mission at item {mission.current} of {mission.count}",
            )
        self._drive_to(x, y, given=True)

    def start_mission(self, waypoints: Sequence[tuple[float, float]], source: str) -> bool:
        """Drive ``waypoints`` (local ENU metres) in order, at once, in place of any goal or mission;
        ``source`` names who gave them in the events. True if started; refused whole, the mission in force
        kept (a ``mission_rejected`` event), when one is outside the geofence, as ``set_goal`` refuses a
        goal, or before the estimator has a datum: a ground station, which sees the mission as waypoints
        in MAV_FRAME_GLOBAL_INT through the datum, would be told there is none while the rover drives one.
        ``ParameterError`` (nothing changed) for no waypoint or one not finite."""
        for index, (x, y) in enumerate(waypoints):
            if self._outside_fence(x, y):
                self._event(
                    "mission_rejected",
                    "warning",
                    f"mission from {source}: waypoint {index} ({x:.2f}, {y:.2f}) is outside the geofence",
                )
                return False
        datum = self._estimator.datum
        if datum is None:
            self._event(
                "mission_rejected",
                "warning",
                f"mission from {source}: no ENU datum yet (no GPS fix), a ground station could not follow it",
            )
            return False
        self._load(waypoints, source)  # ParameterError before anything changes: no waypoint, NaN
        geodetic = [to_geodetic(datum, x, y, 0.0) for x, y in self.mission.waypoints]
        self.server.replace([(lat, lon) for lat, lon, _ in geodetic])
        self._drive_to(*self.mission.set_current(0), given=True)
        return True

    def goal_from_ground_station(self, request: GoalRequest) -> None:
        """A ground station's goal (latitude, longitude) placed through the estimator's datum and driven as
        ``set_goal`` drives one; refused (``goal_rejected``) before the datum is known."""
        placed = self._placed(request.lat_deg, request.lon_deg)
        if placed is None:
            self._event("goal_rejected", "warning", "MAVLink goal before the first GPS fix: no datum yet")
            return
        self.set_goal(*placed)

    def take_message(self, link: MavlinkLink, reading: MissionMessage) -> None:
        """A ground station's mission message: the server answers it; what it changes is driven here."""
        change = self.server.take(link, reading.msg)
        if change is None:
            return
        who = f"{change.sysid}/{change.compid}"
        if isinstance(change, MissionAccepted):
            self._take_upload(change, f"MAVLink upload by {who} on the {link.name} link")
        elif isinstance(change, StartRequest):
            self._start_at(change.first, "mission_started", f"mission started at item {change.first}", who)
        elif isinstance(change, MissionCleared):
            if self.mission.clear():
                self._guidance.clear_goal()
                self._event("mission_cleared", "info", f"mission cleared by {who}: the rover holds")
            else:
                self._event("mission_cleared", "info", f"mission cleared by {who}")
        elif isinstance(change, CurrentRequested):
            self._start_at(change.seq, "mission_current", f"item {change.seq}", who, " made current")

    def end_tick(self, arrived: bool) -> None:
        """After a tick's records (as the trial runner once set the next goal between ticks): ``arrived``,
        guidance reports ARRIVED, takes a mission being driven on to its next waypoint; then the server's
        own tick (MISSION_CURRENT, transfer timeouts)."""
        mission = self.mission
        mission_state = mission.state
        if mission_state is MissionState.ACTIVE and arrived:
            self._item_reached()
            mission_state = mission.state
        self.server.tick(mission.current, mission_state)

    def _load(self, waypoints: Sequence[tuple[float, float]], source: str, note: str = "") -> None:
        """The mission in force replaced (not driven yet: ``Mission.set_current`` starts it)."""
        self.mission.load(waypoints)
        count = self.mission.count
        listed = ", ".join(f"({x:.2f}, {y:.2f})" for x, y in self.mission.waypoints)
        noun = "waypoint" if count == 1 else "waypoints"
        self._event("mission", "info", f"mission of {count} {noun} from {source}: {listed}{note}")

    def _drive_to(self, x: float, y: float, *, given: bool) -> None:
        """Guidance's new goal: a single goal or a mission's waypoint. ``given``: chosen from outside (a
        goal, a mission started, an item made current), which clears the stuck and stall latches (the
        operator chose where to go next); a mission advancing by itself to its next waypoint does not: a
        rover stuck at one waypoint is as stuck on the way to the next."""
        self._guidance.set_goal(x, y)
        if given:
            self._new_goal()
        self._event("goal", "info", f"new goal ({x:.2f}, {y:.2f})")

    def _outside_fence(self, x: float, y: float) -> bool:
        """Whether (x, y), local ENU metres, is outside ``[safety] fence`` (none: never)."""
        fence = self._fence
        return bool(fence) and not inside_polygon(x, y, fence)

    def _placed(self, lat_deg: float, lon_deg: float) -> tuple[float, float] | None:
        """A latitude and longitude in local ENU metres through the estimator's datum (the rover's
        altitude: a rover ignores it); None before the datum is known."""
        datum = self._estimator.datum
        if datum is None:
            return None
        x, y, _ = to_enu(datum, lat_deg, lon_deg, datum.alt_m)
        return x, y

    def _place_waypoint(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        """An uploaded waypoint in local ENU metres, as a MAVLink goal is placed; ``MissionItemRefused``
        before the datum is known or outside the geofence (the upload is refused)."""
        placed = self._placed(lat_deg, lon_deg)
        if placed is None:
            raise MissionItemRefused("no ENU datum yet (no GPS fix): waypoints cannot be placed")
        if self._outside_fence(*placed):
            raise MissionItemRefused(f"waypoint ({placed[0]:.2f}, {placed[1]:.2f}) is outside the geofence")
        return placed

    def _take_upload(self, change: MissionAccepted, source: str) -> None:
        """An upload replaces the mission; it is driven at once, from item 0, only in place of a mission
        being driven (as ArduPilot and PX4 go on in their mission modes). Otherwise, parked, a mission
        complete or paused for a single goal, it waits for MISSION_START or MISSION_SET_CURRENT: ground
        stations treat an upload as editing the plan, and a separate command as starting it."""
        driving = self.mission.state is MissionState.ACTIVE
        note = (
            "; driven from item 0 in place of the mission being driven"
            if driving
            else "; not started: MISSION_START or MISSION_SET_CURRENT drives it"
        )
        self._load(change.waypoints, source, note)
        if driving:
            self._drive_to(*self.mission.set_current(0), given=True)

    def _start_at(self, seq: int, kind: str, what: str, who: str, verb: str = "") -> None:
        """A ground station made item ``seq`` current or started the mission there: it is driven from it."""
        try:
            waypoint = self.mission.set_current(seq)
        except ParameterError as err:
            # The server asks only for an item it holds, and holds the mission driven; should the two
            # ever differ, a ground station's message must still not stop the loop.
            _log.warning("%s from %s not taken: %s", kind, who, err)
            return
        self._event(kind, "info", f"{what} of {self.mission.count}{verb} by {who}")
        self._drive_to(*waypoint, given=True)

    def _item_reached(self) -> None:
        """Guidance reports ARRIVED at the mission's current waypoint: on to the next, or the end."""
        mission = self.mission
        seq, count = mission.current, mission.count
        x, y = mission.waypoints[seq]
        self._event("mission_item_reached", "info", f"item {seq} of {count} ({x:.2f}, {y:.2f}) reached")
        self.server.item_reached(seq)
        following = mission.reached()
        if following is None:
            self._event("mission_complete", "info", f"mission complete: its {count} waypoint(s) reached")
        else:
            self._drive_to(*following, given=False)  # the mission's own step: the latches stand
