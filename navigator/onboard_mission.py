"""Goals and missions for guidance: what the onboard stack is told to drive to, turned into guidance's goal.

A single goal (Zenoh, a ground station's MAVLink goal, ``rover run --goal``) is driven at once and pauses
the mission; a mission (``navigator.mission``), handed over by the trial runner or uploaded by a ground
station with the MAVLink mission protocol (``firmware_bridge.mavlink_mission``, whose server answers the
protocol and hands over what a transfer changes), is driven waypoint by waypoint: an upload at once only
in place of a mission being driven, else on MISSION_START or MISSION_SET_CURRENT. ``MissionDriver`` holds
the mission and its server for the onboard stack (``navigator.onboard``), which calls ``end_tick`` after
each tick's records: the next waypoint becomes the goal at the end of the tick in which guidance reports
ARRIVED.

A speed change (MAV_CMD_DO_CHANGE_SPEED) the mission comes to is applied at once, as guidance's speed limit
(``RouteGuidance.limit_speed``), and the mission goes on to its next item in the same call. The limit stands
for the rest of the mission, until a later speed change, or until the mission is paused by a single goal,
cleared, replaced or complete (the spec's "until it is overridden or there is a mode change": ArduPilot's
Guided mode and PX4 reset the speed when the vehicle leaves its mission). A MISSION_SET_CURRENT or
MISSION_START that enters the mission part-way sets the speed the items it skipped would have left (the last
speed change before the item, or none), as PX4 replays the last speed change before the item it resumes at:
a slow stretch stays slow however a ground station jumps in. A resume at the very item a single goal paused
the mission at takes back the limit in force then (on a jump's later lap the list before it can differ).
A return to launch the mission comes to lifts the limit: ArduPilot Rover's RTL drives at its own speed
(RTL_SPEED, else the default), so a slow stretch before it does not slow the way home; the speed changes
after it set the limit again as they come.

Home (``navigator.onboard_home.HomeKeeper``, ``home``) is where a return to launch drives: as a mission item
the mission comes to (home as it is then becomes the goal; reached, the mission goes on to its next
item, as ArduPilot Rover's Auto mode does), or as a
ground station's MAV_CMD_NAV_RETURN_TO_LAUNCH (a single goal to home: it pauses the mission like any). A
loiter item is a waypoint with a hold: LOITER_TIME's for its time, LOITER_UNLIM's until the operator moves
the mission on (a current item set, a start, a clear, a new goal or mission).

A jump (MAV_CMD_DO_JUMP) the mission comes to is passed as a speed change is (a ``mission_jump`` event, no
MISSION_ITEM_REACHED): on at its target while its count allows, else past it; the speed changes a loop
passes again apply again, those a jump skips do not. The counts belong to a run of the mission: an upload,
MISSION_START (but at the item a single goal paused the mission at: that resumes the laps) and
MISSION_SET_CURRENT on a mission not under way (not started, complete) start them from 0; a resume of a
paused mission and
MISSION_SET_CURRENT within a mission being driven keep them (the spec: "mission jump repeat counters are
not reset"). A delay (MAV_CMD_NAV_DELAY) is a hold where the rover is: no goal (guidance IDLE) for its
seconds on the stack's clock, the item current, any new goal ending it.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

from estimator.estimator import Estimator
from estimator.geodesy import to_enu, to_geodetic
from firmware_bridge.mavlink_commands import GoalRequest, StartRequest
from firmware_bridge.mavlink_home import Home, HomeRefusal, ReturnToLaunch, is_home_command
from firmware_bridge.mavlink_link import MavlinkLink
from firmware_bridge.mavlink_mission import (
    CurrentRequested,
    MissionAccepted,
    MissionCleared,
    MissionItemRefused,
    MissionLink,
    MissionMessage,
    MissionServer,
    MissionStep,
)
from firmware_bridge.mission_hold import HOLD_UNLIMITED
from firmware_bridge.mission_jump import JUMP_FOREVER
from logs.clock import Clock, to_ns
from navigator.errors import ParameterError
from navigator.fence_shape import Polygon, inside_polygon
from navigator.mission import (
    Delay,
    DrivenItem,
    Jump,
    JumpPassed,
    Leg,
    Mission,
    MissionState,
    SpeedChange,
    Waypoint,
)
from navigator.onboard_home import HomeKeeper
from navigator.route_guidance import RouteGuidance
from navigator.safety import EventSink

_log = logging.getLogger(__name__)


class MissionDriver:
    """Single goals, missions and the MAVLink mission protocol's changes, as goals for ``RouteGuidance``.

    ``mission`` is the mission in force and its progress, ``server`` the MAVLink mission protocol's server
    (the mission as uploaded, the transfer under way). ``estimator``: its datum places waypoints and goals
    given in latitude and longitude; ``new_goal`` (the safety supervisor's) clears the stuck and stall
    latches on a goal given from outside; ``fence``: ``[safety] fence`` (empty: none), outside which goals
    and waypoints are refused; ``event`` publishes a ``safety/events`` message; ``slowest_speed_mps``: the
    lowest DO_CHANGE_SPEED an upload may set (``firmware_bridge.mission_speed.slowest_mission_speed``);
    ``autopilot``: the autopilot's link, never told where our home is (its home is its own).
    """

    def __init__(
        self,
        clock: Clock,
        estimator: Estimator,
        guidance: RouteGuidance,
        new_goal: Callable[[], None],
        fence: Polygon,
        event: EventSink,
        slowest_speed_mps: float = 0.0,
        autopilot: MavlinkLink | None = None,
    ) -> None:
        self._estimator = estimator
        self._guidance = guidance
        self._new_goal = new_goal
        self._fence = fence
        self._event = event
        self._clock = clock
        self.mission = Mission()
        self.server = MissionServer(clock, self._place_waypoint, slowest_speed_mps=slowest_speed_mps)
        self._autopilot = autopilot
        self.home = HomeKeeper(
            clock, estimator, self._placed, self._outside_fence, event, listeners=self._home_listeners
        )
        # While the rover waits at a waypoint with a hold time: (that item, when it goes on in clock ns; None:
        # never, a loiter without end). Honoured only while that item is current in a mission driven; any
        # new goal ends it (_drive_to).
        self._hold: tuple[int, int | None] | None = None
        # The item a single goal paused the mission at and the mission's speed limit in force then: a resume
        # at that item drives at that speed again (in a jump's later lap the list before the item can say
        # otherwise). None while the mission is not paused.
        self._paused_at: tuple[int, float | None] | None = None

    def set_goal(self, x: float, y: float) -> None:
        """A single goal: driven at once, in place of the mission being driven (which is paused: setting
        a current item drives it again). One outside the geofence is refused (``goal_rejected``)."""
        if self._outside_fence(x, y):
            self._event("goal_rejected", "warning", f"goal ({x:.2f}, {y:.2f}) is outside the geofence")
            return
        mission = self.mission
        in_force = self.speed_limit_mps
        if mission.pause():
            self._paused_at = (mission.current, in_force)
            self._event(
                "mission_paused",
                "info",
                f"a single goal replaced the mission at item {mission.current} of {mission.count}",
            )
            # A speed change persists "until it is overridden or there is a mode change" (the MAVLink
            # spec); leaving the mission for a goal is that change, as ArduPilot's Guided mode and PX4
            # reset the speed. Resuming at that item sets it again (_start_at).
            self._lift_speed_limit("a single goal paused the mission")
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
        geodetic = [to_geodetic(datum, point.x, point.y, 0.0) for point in self.mission.waypoints]
        self.server.replace([(lat, lon) for lat, lon, _ in geodetic])
        self._follow(self.mission.set_current(0), given=True)
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
        """A ground station's mission message: the server answers it; what it changes is driven here. A
        home command (``firmware_bridge.mavlink_home``) is answered by ``home``; a return to launch
        accepted is driven as a single goal to home."""
        msg = reading.msg
        if is_home_command(msg):
            home = self.home.take(link, msg)
            if home is not None:
                who = f"{msg.get_srcSystem()}/{msg.get_srcComponent()}"
                self._event(
                    "return_to_launch",
                    "info",
                    f"return to launch by {who}: home ({home.x:.2f}, {home.y:.2f})",
                )
                self.set_goal(home.x, home.y)
            return
        change = self.server.take(link, msg)
        if change is None:
            return
        who = f"{change.sysid}/{change.compid}"
        if isinstance(change, MissionAccepted):
            self._take_upload(change, f"MAVLink upload by {who} on the {link.name} link")
        elif isinstance(change, StartRequest):
            # A start is a new run of the mission (every jump's count from 0), but at the item a single
            # goal paused it at: that resumes the laps it was driving. A start elsewhere on a paused
            # mission is a new run too (back to item 0 with lap 2's counts would be neither).
            mission = self.mission
            restart = not (mission.state is MissionState.PAUSED and change.first == mission.current)
            what = f"mission started at item {change.first}"
            self._start_at(change.first, "mission_started", what, who, restart=restart)
        elif isinstance(change, MissionCleared):
            if self.mission.clear():
                self._guidance.clear_goal()
                self._event("mission_cleared", "info", f"mission cleared by {who}: the rover holds")
            else:
                self._event("mission_cleared", "info", f"mission cleared by {who}")
            self._lift_speed_limit("the mission was cleared")
        elif isinstance(change, CurrentRequested):
            # A new run only for a mission not under way (not started, complete); within a mission being
            # driven or paused the jump counts go on, as the spec says of MISSION_SET_CURRENT.
            restart = self.mission.state in (MissionState.NOT_STARTED, MissionState.COMPLETE)
            what = f"item {change.seq}"
            self._start_at(change.seq, "mission_current", what, who, " made current", restart=restart)

    def end_tick(self, arrived: bool) -> None:
        """After a tick's records (as the trial runner once set the next goal between ticks): ``arrived``,
        guidance reports ARRIVED, takes a mission being driven on to its next waypoint; then the server's
        own tick (MISSION_CURRENT, transfer timeouts). Home follows the estimate until it is used
        (``HomeKeeper.observe``)."""
        self.home.observe()
        mission = self.mission
        hold = self._hold
        if hold is not None and (mission.state is not MissionState.ACTIVE or hold[0] != mission.current):
            hold = self._hold = None  # the mission changed under it: cleared, replaced, paused, jumped
        if mission.state is MissionState.ACTIVE:
            if hold is not None:
                until = hold[1]
                if until is not None and self._clock.now_ns() >= until:
                    self._hold = None
                    self._wait_over()
            elif arrived:
                self._item_reached()
        self.server.tick(mission.current, mission.state)

    def _load(self, items: Sequence[MissionStep], source: str, note: str = "") -> None:
        """The mission in force replaced (not driven yet: ``Mission.set_current`` starts it); the old
        one's speed limit with it."""
        mission = self.mission
        mission.load(items)
        self._lift_speed_limit("the mission was replaced")
        count, waypoints = mission.count, len(mission.waypoints)
        listed = ", ".join(_listed(item) for item in mission.items)
        noun = "waypoint" if waypoints == 1 else "waypoints"
        if waypoints == count:
            what = f"{count} {noun}"
        else:
            returns = sum(isinstance(item, ReturnToLaunch) for item in mission.items)
            changes = sum(isinstance(item, SpeedChange) for item in mission.items)
            jumps = sum(isinstance(item, Jump) for item in mission.items)
            delays = sum(isinstance(item, Delay) for item in mission.items)
            kinds = [f"{waypoints} {noun}"]
            if changes:
                kinds.append(f"{changes} speed change{'' if changes == 1 else 's'}")
            if returns:
                kinds.append(f"{returns} return to launch")
            if jumps:
                kinds.append(f"{jumps} jump{'' if jumps == 1 else 's'}")
            if delays:
                kinds.append(f"{delays} delay{'' if delays == 1 else 's'}")
            what = f"{count} items ({', '.join(kinds)})"
        self._event("mission", "info", f"mission of {what} from {source}: {listed}{note}")

    def _drive_to(self, x: float, y: float, *, given: bool) -> None:
        """Guidance's new goal: a single goal or a mission's waypoint. ``given``: chosen from outside (a
        goal, a mission started, an item made current), which clears the stuck and stall latches (the
        operator chose where to go next); a mission advancing by itself to its next waypoint does not: a
        rover stuck at one waypoint is as stuck on the way to the next."""
        self._hold = None
        self._guidance.set_goal(x, y)
        if given:
            self._new_goal()
        self._event("goal", "info", f"new goal ({x:.2f}, {y:.2f})")

    def _home_listeners(self) -> list[MissionLink]:
        """The links a new home is told on: the ground stations following the mission, not the autopilot."""
        autopilot = self._autopilot
        return [link for link in self.server.followers if link is not autopilot]

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
        self._load(change.steps, source, note)
        if driving:
            self._follow(self.mission.set_current(0), given=True)

    def _start_at(
        self, seq: int, kind: str, what: str, who: str, verb: str = "", *, restart: bool = True
    ) -> None:
        """A ground station made item ``seq`` current or started the mission there: it is driven from it,
        at the speed the items before it set (``Mission.speed_set_before``); ``restart``: every jump's
        count from 0 (a new run), else they go on (``Mission.set_current``). A resume at the item a single
        goal paused the mission at drives at the speed in force then, instead."""
        paused_at, self._paused_at = self._paused_at, None
        resumed = paused_at is not None and paused_at[0] == seq and self.mission.state is MissionState.PAUSED
        try:
            leg = self.mission.set_current(seq, restart=restart)
        except ParameterError as err:
            # The server asks only for an item it holds, and holds the mission driven; should the two
            # ever differ, a ground station's message must still not stop the loop.
            _log.warning("%s from %s not taken: %s", kind, who, err)
            return
        self._event(kind, "info", f"{what} of {self.mission.count}{verb} by {who}")
        changes = leg.speed_changes
        if (not changes or changes[0][1].keep) and not isinstance(leg.target, ReturnToLaunch):
            # One mechanism for the speed, jumps or not: entering part-way replays the items before the
            # entry in the list (a jump on the way is not followed back); after that, each speed change is
            # applied as the mission passes it, a jump's loop round included.
            # The leg does not begin by setting a speed of its own: the items before seq say the speed it
            # starts from (a "no change" first keeps that one, and says so). A return to launch drives at
            # the rover's own speed whatever came before (_return_home). A resume where the mission was
            # paused takes the speed it was driving at: in a jump's later lap that can be another.
            if resumed and paused_at is not None:
                self._speed_as_paused(seq, paused_at[1])
            else:
                self._speed_from_before(seq)
        if not self._follow(leg, given=True):
            # Only speed changes from ``seq`` to the end: nothing left to drive to.
            self._guidance.clear_goal()
            self._complete(f"no waypoint from item {seq}: the rover holds")

    def _item_reached(self) -> None:
        """Guidance reports ARRIVED at the mission's current waypoint: the ground station told at once
        (MISSION_ITEM_REACHED, as ArduPilot says it on arrival); then its hold, if it has one (the rover
        waits there, ARRIVED, the item still current), or on to the next item, or the end."""
        mission = self.mission
        seq, count = mission.current, mission.count
        item = mission.items[seq]
        if isinstance(item, ReturnToLaunch):
            goal = self._guidance.goal  # home as it was driven to
            where = "home" if goal is None else f"home ({goal.x:.2f}, {goal.y:.2f})"
            self._event(
                "mission_item_reached", "info", f"item {seq} of {count} (return to launch) {where} reached"
            )
            self.server.item_reached(seq)
            # On to the next item, as ArduPilot Rover's Auto goes on once RTL reaches home; the last item:
            # the mission is complete and the rover holds at home.
            self._advance(f"returned to launch at item {seq}: the rover holds at home")
            return
        waypoint = mission.current_waypoint()
        self._event(
            "mission_item_reached",
            "info",
            f"item {seq} of {count} ({waypoint.x:.2f}, {waypoint.y:.2f}) reached",
        )
        self.server.item_reached(seq)
        hold_s = waypoint.hold_s
        if hold_s == HOLD_UNLIMITED:
            self._hold = (seq, None)
            self._event(
                "mission_hold",
                "info",
                f"item {seq} of {count}: holding until the operator moves the mission on (loiter unlimited)",
            )
            return
        if hold_s > 0.0:
            self._hold = (seq, self._clock.now_ns() + to_ns(hold_s))
            self._event("mission_hold", "info", f"item {seq} of {count}: holding {hold_s:g} s")
            return
        self._advance()

    def _wait_over(self) -> None:
        """A hold at a waypoint or a delay ran out: a delay is reported done (a ``mission_item_reached``
        event and MISSION_ITEM_REACHED, as ArduPilot reports a NAV command completed), then on to the next
        item."""
        mission = self.mission
        seq = mission.current
        item = mission.items[seq]
        if isinstance(item, Delay):
            detail = f"item {seq} of {mission.count} (delay {item.seconds:g} s) done"
            self._event("mission_item_reached", "info", detail)
            self.server.item_reached(seq)
        self._advance()

    def _advance(self, done: str | None = None) -> None:
        """From the item reached (and held at) to the next item, or the end (``done``: what the
        ``mission_complete`` event says then, by default the waypoints reached)."""
        mission = self.mission
        # given=False: the mission's own step, the latches stand.
        if not self._follow(mission.reached(), given=False):
            self._complete(done or f"its {len(mission.waypoints)} waypoint(s) reached")

    def _complete(self, detail: str) -> None:
        """The mission is complete: a ``mission_complete`` event, and its speed limit lifted."""
        self._event("mission_complete", "info", f"mission complete: {detail}")
        self._lift_speed_limit("the mission is complete")

    def _follow(self, leg: Leg, *, given: bool) -> bool:
        """Apply the speed changes the mission passed, in order, then drive to its waypoint, or home for a
        return to launch (``given``: see ``_drive_to``). False when no waypoint was left: the mission is
        complete (``_complete``; a return to launch with no home completes it itself, ``_return_home``)."""
        for seq, change in leg.speed_changes:
            self._change_speed(seq, change)
        for passed in leg.jumps:
            self._event("mission_jump", "info", self._jump_detail(passed))
        target = leg.target
        if target is None:
            return False
        if isinstance(target, ReturnToLaunch):
            return self._return_home(given=given)
        if isinstance(target, Delay):
            self._wait(target)
            return True
        self._drive_to(target.x, target.y, given=given)
        return True

    def _jump_detail(self, passed: JumpPassed) -> str:
        """A jump passed, as its ``mission_jump`` event says it."""
        item = f"item {passed.seq} of {self.mission.count}"
        target, repeat = passed.jump
        times = "for ever" if repeat == JUMP_FOREVER else f"of {repeat}"
        if passed.taken:
            return f"{item}: jump to item {target} ({passed.done} {times})"
        return f"{item}: jumped to item {target} {passed.done} of {repeat} times: on past it"

    def _wait(self, delay: Delay) -> None:
        """The mission came to a delay: the rover held where it is (no goal: guidance IDLE) until
        ``delay.seconds`` on the stack's clock have passed (``end_tick``), the item current; a
        ``mission_delay`` event. Any new goal ends it, as it ends a hold at a waypoint."""
        mission = self.mission
        seq = mission.current
        self._guidance.clear_goal()
        self._hold = (seq, self._clock.now_ns() + to_ns(delay.seconds))
        self._event(
            "mission_delay",
            "info",
            f"item {seq} of {mission.count}: waiting {delay.seconds:g} s, the rover held where it is",
        )

    def _return_home(self, *, given: bool) -> bool:
        """The mission came to a return to launch: home as it is now becomes the goal (a
        ``return_to_launch`` event). With no home to drive to (no healthy estimate yet, home outside the
        geofence) the mission ends there, COMPLETE on the return item (``Mission.end_here``;
        MISSION_CURRENT says COMPLETE, as the event does), whatever items follow, and the rover holds (a
        warning event saying why, then ``mission_complete``). True either way: the item was dealt with.

        Not ArduPilot's way: AP_Mission's ``advance_current_nav_cmd`` goes on to the next NAV command when
        one fails to start. A rover told to come home that cannot should not drive on, away from it, to
        the items planned for after home; it stops and the operator decides."""
        mission = self.mission
        seq, count = mission.current, mission.count
        target: Home | HomeRefusal = self.home.return_target()
        if isinstance(target, HomeRefusal):
            self._event(
                "return_to_launch", "warning", f"item {seq} of {count}: {target.reason}: the rover holds"
            )
            mission.end_here()
            self._guidance.clear_goal()
            self._complete(f"no home to return to at item {seq}: the rover holds")
            return True
        self._event(
            "return_to_launch",
            "info",
            f"item {seq} of {count}: return to launch: home ({target.x:.2f}, {target.y:.2f})",
        )
        self._lift_speed_limit(f"item {seq} of {count} returns to launch at the rover's own speed")
        self._drive_to(target.x, target.y, given=given)
        return True

    def _change_speed(self, seq: int, change: SpeedChange) -> None:
        """A speed change item reached: guidance's limit from now on; a ``mission_speed`` event and
        MISSION_ITEM_REACHED, as for a waypoint reached (ArduPilot and PX4 report a DO item done so too)."""
        item = f"item {seq} of {self.mission.count}"
        limit = change.limit_mps
        if change.keep:
            in_force = self.speed_limit_mps
            kept = "none" if in_force is None else f"{in_force:.2f} m/s"
            detail = f"{item}: speed unchanged (DO_CHANGE_SPEED -1): the mission's limit stays {kept}"
        elif limit is None:
            detail = f"{item}: back to the default speed: no mission speed limit"
            self._guidance.limit_speed(None)
        else:
            top = self._guidance.max_speed_mps
            detail = f"{item}: mission speed limit {limit:.2f} m/s"
            if limit >= top:
                detail += f": at or above the rover's max_speed_mps {top:.2f}, which stays its limit"
            self._guidance.limit_speed(limit)
        self._event("mission_speed", "info", detail)
        self.server.item_reached(seq)

    def _speed_from_before(self, seq: int) -> None:
        """The mission's speed limit as the items before ``seq`` left it (the mission entered at ``seq``
        skipped them): a ``mission_speed`` event when that changes the limit in force; no
        MISSION_ITEM_REACHED (those items were not reached)."""
        before = self.mission.speed_set_before(seq)
        limit = None if before is None else before[1].limit_mps
        if limit == self.speed_limit_mps:
            return
        if before is None:
            returned = any(isinstance(item, ReturnToLaunch) for item in self.mission.items[:seq])
            detail = (
                f"a return to launch before item {seq}: no mission speed limit"
                if returned
                else f"no speed change before item {seq}: no mission speed limit"
            )
        elif limit is None:
            detail = f"item {before[0]} before item {seq}: back to the default speed: no mission speed limit"
        else:
            detail = f"item {before[0]} before item {seq}: mission speed limit {limit:.2f} m/s"
        self._guidance.limit_speed(limit)
        self._event("mission_speed", "info", detail)

    def _speed_as_paused(self, seq: int, limit: float | None) -> None:
        """The mission's speed limit as it was when a single goal paused the mission at item ``seq``: a
        ``mission_speed`` event when that changes the limit in force."""
        if limit == self.speed_limit_mps:
            return
        as_paused = "no mission speed limit" if limit is None else f"mission speed limit {limit:.2f} m/s"
        self._guidance.limit_speed(limit)
        self._event("mission_speed", "info", f"resumed at item {seq}: {as_paused}, as when it was paused")

    @property
    def speed_limit_mps(self) -> float | None:
        """The mission's speed limit in force (guidance holds it), or None."""
        return self._guidance.core.mission_speed_mps

    def _lift_speed_limit(self, why: str) -> None:
        """The mission's speed limit, if one is in force, lifted (a ``mission_speed`` event saying why)."""
        in_force = self.speed_limit_mps
        if in_force is None:
            return  # no event: a mission without speed changes records what it always did
        self._guidance.limit_speed(None)
        self._event("mission_speed", "info", f"mission speed limit {in_force:.2f} m/s lifted: {why}")


def _listed(item: DrivenItem) -> str:
    """A mission item as the ``mission`` event lists it (a waypoint without a hold as it always was)."""
    if isinstance(item, ReturnToLaunch):
        return "return to launch"
    if isinstance(item, Waypoint):
        if item.hold_s == HOLD_UNLIMITED:
            held = " hold until moved on"
        else:
            held = f" hold {item.hold_s:g} s" if item.hold_s > 0.0 else ""
        return f"({item.x:.2f}, {item.y:.2f}){held}"
    if isinstance(item, Jump):
        times = "for ever" if item.repeat == JUMP_FOREVER else f"{item.repeat} times"
        return f"jump to item {item.target} {times}"
    if isinstance(item, Delay):
        return f"delay {item.seconds:g} s"
    if item.keep:
        return "speed unchanged"
    return "speed default" if item.limit_mps is None else f"speed {item.limit_mps:.2f} m/s"
