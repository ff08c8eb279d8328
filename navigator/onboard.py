"""The onboard loop: links -> estimator -> guidance -> safety supervisor -> wheel commands, tick by tick.

``OnboardStack.step()`` is one control tick. The same object runs on the rover (``navigator.paced_loop``
calls ``ingest`` until the pacing measurement, the IMU sample by default, has arrived, then ``step`` at
once, with a fixed-rate deadline as the fallback), in lockstep HIL (the trial runner calls ``step`` after
advancing the simulated clock; the sample read inside the step paces it) and in tests. It owns no clock
and opens no connection: both are handed in.

A tick's critical path is: read the links, estimate, guide, supervise, mix, send the wheel commands.
Everything else (heartbeat, the tick's own topics, the map) comes after the send, and records made on
the critical path are held back until then when the stack is given a ``DeferredSink``.

Guidance (plan on a new goal, repair the plan as obstacles are perceived, follow the path) is
``navigator.guidance.Guidance`` behind a start-up gate (``navigator.route_guidance.RouteGuidance``); the
safety supervisor (``navigator.safety``) decides how much of guidance's command reaches the wheels.

Goals come one at a time (``set_goal``) or as a mission of waypoints driven in order (``start_mission``, or
uploaded over the MAVLink mission protocol): ``navigator.onboard_mission.MissionDriver`` turns both into
guidance's goal for the stack.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from concurrent.futures import Executor

from estimator.estimator import Estimator
from estimator.pose import PoseEstimate
from firmware_bridge.can_health import CanLinkState
from firmware_bridge.can_link import CanLink
from firmware_bridge.distance_sensor import RangeBeam
from firmware_bridge.mavlink_commands import GoalRequest, StopRequest
from firmware_bridge.mavlink_link import AttitudeSample, GpsFix, ImuSample, MavlinkLink
from firmware_bridge.mavlink_mission import (
    MissionMessage,
)
from firmware_bridge.mission_speed import slowest_mission_speed
from firmware_bridge.obstacle_scan import ObstacleScan
from logs import topics
from logs.clock import NS_PER_S, Clock
from logs.commands import CommandSource, RoverCommand, command_record
from logs.sink import MessageSink
from navigator.climb_learning import learned_class, trustworthy_dig_in
from navigator.config import RoverConfig
from navigator.deferred_sink import DeferredSink
from navigator.event_texts import mav_severity, status_text, told
from navigator.guidance import GuidanceOutput
from navigator.map_message import grid_message
from navigator.mission import Mission, MissionState
from navigator.mixing import mix_skid_steer
from navigator.odometry_frame import OdometryFrame
from navigator.onboard_learning import TractionLearning
from navigator.onboard_mission import MissionDriver
from navigator.onboard_recovery import DigInRecovery
from navigator.perception import ObstacleSource, obstacles_record
from navigator.planner import Path, Planner
from navigator.route_guidance import Goal, GuidanceCommand, Mode, RouteGuidance
from navigator.safety import NO_PROGRESS, TIP_OVER, SafetyInputs, SafetyMode, SafetySupervisor
from navigator.scan_tracker import ScanTracker
from navigator.scan_watch import RangefinderWatch, ScanWatch
from navigator.start_up_checks import StartUpChecks
from navigator.terrain import TerrainMap
from navigator.wheel_snapshot import WheelSnapshot

_log = logging.getLogger(__name__)

HEARTBEAT_PERIOD_NS = NS_PER_S
# The autopilot's AHRS heading (compass-aided yaw, good to a few degrees) is fused as a measurement.
AHRS_HEADING_STD_RAD = math.radians(5.0)
# MAVLink GPS_FIX_TYPE 3 = 3D fix; anything less does not count as "GPS present" for the GPS failsafe.
MIN_GPS_FIX_TYPE = 3
# A rejected input repeating every sample is logged on its first occurrence and then every this many.
_LOG_EVERY = 100


# Guidance's modes in which the wheels are meant to turn (read every tick).
_DRIVING_MODES = (Mode.DRIVING, Mode.YIELDING, Mode.RECOVERING)


class _EventFn:
    """Publishes one ``safety/events`` message (and logs it) at the clock's now, and tells the ground
    station the ones an operator must see (``navigator.event_texts``) as STATUSTEXT on ``links``."""

    def __init__(self, clock: Clock, sink: MessageSink, links: Sequence[MavlinkLink] = ()) -> None:
        self._clock = clock
        self._sink = sink
        self._links = tuple(links)

    def __call__(self, kind: str, severity: str, detail: str) -> None:
        now = self._clock.now_ns()
        level = logging.INFO if severity == "info" else logging.WARNING
        _log.log(level, "%s: %s", kind, detail)
        self._sink.publish(
            topics.SAFETY_EVENTS,
            now,
            {"timestamp": topics.stamp(now), "kind": kind, "severity": severity, "detail": detail},
        )
        if told(kind):
            text, mav_level = status_text(kind, detail), mav_severity(severity)
            for link in self._links:  # a failed write is counted and logged by the link
                link.send_status_text(text, mav_level)


class OnboardStack:
    """Estimator, guidance, safety supervisor and mixer between a CAN link and a MAVLink link.

    ``commands`` (optional) delivers goals, e-stops and resumes from the ground (Zenoh); ``obstacles``
    (optional) delivers perceived obstacles (a lidar pipeline on the rover, the simulator in HIL).
    Goals and stops also arrive over MAVLink (the link has already acknowledged them): on the autopilot's
    link when the autopilot forwards them, or on ``ground_station``, a second MAVLink link straight to a
    ground station (as a companion computer behind mavlink-router has).

    ``deferred`` (optional): the ``DeferredSink`` the links and ``sink`` record through; the stack holds it
    from a pacing sample's arrival to the wheel command's send (``navigator.deferred_sink``).
    ``planning`` (optional): the executor planning jobs run on (``navigator.plan_worker``); the default
    plans inline, inside the tick (lockstep: deterministic). The caller owns it and shuts it down.
    ``start_up_report`` (optional) also gets each ``startup_checks`` event as one line (``rover run``
    prints them: an operator at the console sees what the rover waits for, e.g. the autopilot's heartbeat).

    ``mission`` is the mission in force and its progress (``navigator.mission.Mission``; read it, change it
    through ``start_mission``, ``set_goal`` or the MAVLink mission protocol); ``navigator.onboard_mission``
    turns goals and missions into guidance's goal.
    """

    def __init__(
        self,
        config: RoverConfig,
        clock: Clock,
        can_link: CanLink,
        mavlink: MavlinkLink,
        sink: MessageSink,
        terrain: TerrainMap,
        *,
        commands: CommandSource | None = None,
        obstacles: ObstacleSource | None = None,
        ground_station: MavlinkLink | None = None,
        deferred: DeferredSink | None = None,
        planning: Executor | None = None,
        start_up_report: Callable[[str], None] | None = None,
    ) -> None:
        self._config = config
        self._clock = clock
        self._can = can_link
        self._mavlink = mavlink
        self._sink = sink
        self._commands = commands
        self._obstacles = obstacles
        # Obstacles from a range sensor's OBSTACLE_DISTANCE scans on the MAVLink link (a lidar driver on the
        # rover, the HIL peer's simulated lidar) and from rangefinders' DISTANCE_SENSOR readings: tracked
        # here, read like ``obstacles``.
        self.scan_tracker = ScanTracker(config.perception)
        self._odometry_frame = OdometryFrame()
        self._scans_in = False  # a scan arrived since the tracker was last read
        self._ground_station = ground_station
        self._wheels = WheelSnapshot.of(can_link.wheel_status())
        self._terrain = terrain
        self._map_published = False
        # Told to the ground station on its own link when there is one, else through the autopilot, which
        # routes a companion's STATUSTEXT on to the ground station (not both: it would see each twice).
        self._event = _EventFn(clock, sink, (mavlink if ground_station is None else ground_station,))
        self._scan_watch = ScanWatch(self._event)
        self._rangefinder_watch = RangefinderWatch(self._event)
        self.estimator = Estimator(config.estimator, clock, sink)
        self.guidance = RouteGuidance(config, terrain, sink, self._event, planning)
        self.safety = SafetySupervisor(
            config.safety,
            config.vehicle,
            clock.now_ns(),
            self._event,
            controller_ids=config.vesc.controller_ids,
        )
        self._mission_driver = MissionDriver(
            clock,
            self.estimator,
            self.guidance,
            self.safety.new_goal,
            config.safety.fence,
            self._event,
            slowest_mission_speed(
                config.follower.min_speed_mps,
                config.safety.stuck_min_command_mps,
                config.safety.wheel_stall_min_command_mps,
            ),
            autopilot=mavlink,
        )
        self._last_heartbeat_sent_ns: int | None = None
        # Learning from digging in (navigator.climb_learning) and from sliding sideways
        # (navigator.slide_learning): one count per goal or resume (navigator.onboard_learning).
        self._learning = TractionLearning(
            config, clock, terrain, self.guidance, self.safety, sink, self._event
        )
        # The last non-zero speed commanded: its sign says which way the rover was pushed once the hold has
        # stopped the wheels (the learning above reads it).
        self._sent_uphill_mps = 0.0
        # Recovery when dug in and learning does not explain it (navigator.recovery): back out, mark, replan.
        self._recovery = DigInRecovery(config, self.guidance, self.safety, self._event)
        self._start_up = StartUpChecks(self._event, start_up_report)
        self._last_tick_ns: int | None = None
        self._last_gps_ns: int | None = None
        self._last_ground_ns: int | None = None
        self._attitude: AttitudeSample | None = None  # the last with a finite roll and pitch
        self.attitude_rejected = 0  # AHRS attitudes whose roll or pitch was not finite (_reject_tilt)
        self._sent_speed_mps = 0.0
        # As the bus carried them.
        self._sent_wheels_mps: tuple[float, ...] = (0.0,) * len(self._wheels.status_ns)
        self._send_failing_since_ns: int | None = None
        self._sent_at_ns = clock.now_ns()
        self._deferred = deferred
        self._pacing = config.pacing_sensor
        # The links in the order _read_links reads them (the pacing sensor's first), chosen once.
        self._link_readers = (
            (self._read_can, self._read_mavlink)
            if self._pacing == "wheels"
            else (self._read_mavlink, self._read_can)
        )
        self._pacing_rx_ns: int | None = None  # receive time of the newest pacing sample in this read
        # The last tick's sensor-to-command latency: from the receive time of the pacing sample that
        # started it to its wheel commands handed to the bus (None: no pacing sample fed the tick).
        # Meaningful under a real clock; 0 in lockstep.
        self.last_sensor_to_command_ns: int | None = None
        self._watching = False  # the link watches count from the first ingest or tick (_start_watches)
        self._closed = False

    # --- guidance's view, as hil.trial reads it -------------------------------------------------------
    @property
    def mode(self) -> Mode:
        return self.guidance.mode

    @property
    def goal(self) -> Goal | None:
        return self.guidance.goal

    @property
    def path(self) -> Path | None:
        return self.guidance.path

    @property
    def planner(self) -> Planner:
        return self.guidance.planner

    @property
    def safety_mode(self) -> SafetyMode:
        return self.safety.mode

    @property
    def mission(self) -> Mission:
        """The mission in force and its progress (read it; change it through ``start_mission``,
        ``set_goal`` or the MAVLink mission protocol)."""
        return self._mission_driver.mission

    # --- commands from outside (ground station, trial runner, operator) --------------------------------
    def set_goal(self, x: float, y: float) -> None:
        """A single goal, driven at once in place of the mission (``MissionDriver.set_goal``)."""
        self._mission_driver.set_goal(x, y)

    def start_mission(self, waypoints: Sequence[tuple[float, float]], source: str) -> bool:
        """Drive ``waypoints`` (local ENU metres) in order, at once, in place of any goal or mission; True
        if started, False if refused (``MissionDriver.start_mission``: why, and what is kept)."""
        return self._mission_driver.start_mission(waypoints, source)

    def estop(self, source: str) -> None:
        self.safety.estop(source)

    def resume(self, source: str) -> None:
        self.safety.resume(source)

    # --- between ticks ----------------------------------------------------------------------------------
    def ingest(self) -> int | None:
        """Read whatever arrived on the links now and fuse it; returns the receive time of the newest
        pacing sample among it (None if none). The real-time loop calls this between ticks and starts a
        tick on a pacing sample; records stay held for that tick (released otherwise)."""
        now = self._clock.now_ns()
        if not self._watching:
            self._start_watches(now)
        if self._deferred is not None:
            self._deferred.hold()
        self._read_links(now, stop_at_pacing=True)
        received = self._pacing_rx_ns
        if received is None and self._deferred is not None:
            self._deferred.release()
        return received

    def publish_map(self) -> None:
        """Publish ``navigator/map`` now (the first tick does it if nobody did before)."""
        now = self._clock.now_ns()
        self._sink.publish(topics.NAVIGATOR_MAP, now, grid_message(self._terrain, now))
        self._map_published = True

    # --- the control tick ---------------------------------------------------------------------------
    def step(self, trigger_ns: int | None = None) -> None:
        """One control tick. ``trigger_ns``: receive time of the pacing sample that started it, found by
        ``ingest`` just before (the real-time loop); without it the tick reads the links itself and a
        pacing sample among what it reads is its trigger (lockstep)."""
        now = self._clock.now_ns()
        if not self._watching:
            self._start_watches(now)
        if self._deferred is not None:
            self._deferred.hold()
        # Released whatever happens: a tick that raises must not leave its records (and the zero
        # commands close() sends after it) held back from the recording.
        try:
            if trigger_ns is None:
                self._read_links(now)
                trigger = self._pacing_rx_ns
            else:
                # The loop's ``ingest`` read the links an instant ago and found the trigger: reading them
                # again would only put a CAN poll on the sensor-to-command path.
                trigger = trigger_ns
            if self._commands is not None:
                self._read_commands()
            if self._obstacles is not None:
                self._read_obstacles(now, self._obstacles)
            if self._scans_in:
                self._scans_in = False
                self._read_obstacles(now, self.scan_tracker)
            elif self._scan_watch.last_ns is not None:
                self._scan_watch.check(now)
            if self._rangefinder_watch.watches:
                # Every tick: each rangefinder is watched on its own, whatever else came.
                self._rangefinder_watch.check(now)

            pose = self.estimator.pose()
            start_up = self._start_up
            ready = start_up.judge(now, pose, self._mavlink.last_heartbeat_ns is not None, self._wheels.heard)
            if not start_up.passed:
                start_up.report(ready)
            route = self.guidance
            guidance = route.tick(now, pose, ready)
            # Backing off out of a moving obstacle's way, or out of where it dug in, is driving too: the
            # supervisor must let the wheels turn (and judges stuck and stalls on it as on any motion).
            driving = route.mode in _DRIVING_MODES
            decision = self.safety.update(
                self._safety_inputs(now, pose),
                driving,
                "" if driving else route.why_stopped(start_up.not_ready),
            )
            if route.mode is Mode.RECOVERING and decision.mode is not SafetyMode.DRIVING:
                # Another hold (an e-stop, stuck, gps_lost ...) stopped the wheels: the back-out ends where
                # the rover is (its clock would run on while held, and a resume reverse at once).
                route.end_recovery(f"held ({', '.join(decision.faults) or decision.mode._value_})")
            if decision.faults and NO_PROGRESS in decision.faults:
                # Learning first: where it applies it explains the hold; else recovery, if it may.
                self._learn_from_digging_in(pose, decision.faults)
                if self.safety.fault_detail(NO_PROGRESS) is not None:
                    self._recovery.consider(now, pose, decision.faults)
            else:
                # A slide is learned from while it drives (no hold): it plans again and follows the old
                # path until the new plan comes.
                wheels_free = decision.mode is SafetyMode.DRIVING
                self._learning.watch_slide(now, pose, self._attitude, decision.faults, wheels_free)
            speed = guidance.speed_mps * decision.speed_scale
            yaw_rate = guidance.yaw_rate_rps * decision.speed_scale
            self._last_tick_ns = now

            wheel_speeds = mix_skid_steer(speed, yaw_rate, self._config.vehicle)
            can = self._can
            errors_before, tx_before = can.counters.bus_errors, can.counters.tx
            erpm = can.send_wheel_speeds(wheel_speeds)
            counters = can.counters
            failed = counters.tx == tx_before and counters.bus_errors > errors_before
            if not failed:
                self._send_failing_since_ns = None
            elif self._send_failing_since_ns is None:
                self._send_failing_since_ns = now
            self._sent_speed_mps, self._sent_at_ns = speed, now
            if speed != 0.0:
                self._sent_uphill_mps = speed
            erpm_per_mps = can.profile.erpm_per_mps  # computed once per profile
            self._sent_wheels_mps = tuple([e / erpm_per_mps for e in erpm])
            self.last_sensor_to_command_ns = None if trigger is None else self._clock.now_ns() - trigger
        finally:
            if self._deferred is not None:
                self._deferred.release()
        if not self._map_published:
            self.publish_map()
        if self._last_heartbeat_sent_ns is None or now - self._last_heartbeat_sent_ns >= HEARTBEAT_PERIOD_NS:
            self._mavlink.send_heartbeat()
            if self._ground_station is not None:
                self._ground_station.send_heartbeat()
            self._last_heartbeat_sent_ns = now
        mission_driver = self._mission_driver
        mission = mission_driver.mission
        sink = self._sink
        sink.publish(
            topics.WHEELS_COMMAND,
            now,
            {
                "timestamp": topics.stamp(now),
                "speed_mps": wheel_speeds,  # mix_skid_steer's own new list
                "erpm": list(erpm),
                "body_speed_mps": speed,
                "body_yaw_rate_rps": yaw_rate,
            },
        )
        self.estimator.publish_pose(now)
        goal = route.goal
        safety_mode = decision.mode
        state: dict[str, object] = {
            "timestamp": topics.stamp(now),
            # _value_: the plain attribute behind .value (an enum property: a Python-level call).
            "mode": route.mode._value_,
            "goal": {"x": goal.x, "y": goal.y} if goal else {"x": math.nan, "y": math.nan},
            "cross_track_error_m": guidance.cross_track_error_m,
            "speed_limit_mps": guidance.speed_limit_mps * decision.speed_scale,
            "speed_limit_reason": _limit_reason(guidance, safety_mode, decision.speed_scale),
            "target_speed_mps": speed,
            "target_yaw_rate_rps": yaw_rate,
            # The supervisor's word next to guidance's, so the topic never shows DRIVING alone while
            # the wheels are held.
            "safety_mode": safety_mode._value_,
            "failsafes": list(decision.faults),
        }
        mission_state = mission.state
        if mission_state is not MissionState.NONE:
            # Which item guidance's goal is (a recording without missions keeps its messages as they were).
            state["mission"] = {
                "state": mission_state._value_,
                "current": mission.current,
                "count": mission.count,
            }
        sink.publish(topics.NAVIGATOR_STATE, now, state)
        mission_driver.end_tick(route.mode is Mode.ARRIVED)

    def close(self) -> None:
        """Stop the wheels (zero commands) and release the links; safe to call twice."""
        if self._closed:
            return
        self._closed = True
        self.guidance.core.close()
        # Records held by an ingest whose sample started no tick go out first; the zero commands the CAN
        # link sends on close must reach the recording too.
        if self._deferred is not None:
            self._deferred.release()
        try:
            self._can.close()
        finally:
            self._mavlink.close()
            if self._ground_station is not None:
                self._ground_station.close()
            if self._deferred is not None:
                self._deferred.release()

    # --- internals ------------------------------------------------------------------------------------
    def _start_watches(self, now: int) -> None:
        """Start every silence budget (the supervisor's GPS, heartbeat, attitude, wheel and ground-link
        watches, the links' own) now, at the loop's first read: what happens between building the stack and
        running it (the warm-up: ~15 s of compiling on a cold numba cache, while a peer waits for our first
        heartbeat) must not fail safe. A link silent from here on still does, on its budget."""
        self._watching = True
        self.safety.start(now)
        self._mavlink.start_watch(now)
        self._can.start_watch(now)
        if self._ground_station is not None:
            self._ground_station.start_watch(now)

    def _learn_from_digging_in(self, pose: PoseEstimate | None, faults: tuple[str, ...]) -> None:
        """Held for no progress while driving its route up a slope the map shows, its wheels turning: the
        ground could not carry the climb the planner routed it up. Believe its class climbs less
        (``navigator.climb_learning``), plan again and drive on; at most ``MAX_LEARNINGS_PER_GOAL`` times a
        goal or resume (with the slides learned from: ``navigator.onboard_learning``), and only from what it
        can trust, else it stays held for the operator."""
        route, attitude = self.guidance, self._attitude
        if pose is None or attitude is None or not self._learning.may_learn():
            return
        if route.mode is not Mode.DRIVING or TIP_OVER in faults:
            return  # backing out of a cart's way, or tipping: not a climb to learn from
        half_base = 0.5 * self._config.vehicle.wheelbase_m
        axles = self._terrain.ground_under_axles(pose.x, pose.y, pose.yaw, half_base)
        if axles is None or axles[1].terrain_class != axles[2].terrain_class:
            return  # off the map, or two classes under it: which one failed is not known
        rear, ground, front = axles
        pitches = (rear.pitch_rad, ground.pitch_rad, front.pitch_rad)
        pitch = attitude.pitch_rad
        if not trustworthy_dig_in(pitch, pitches, self._sent_uphill_mps, self._wheels.judged_speeds_mps):
            return
        believed = route.classes.get(ground.terrain_class)
        margin = route.planner.climb_margin_rad
        learned = None if believed is None else learned_class(believed, pitch, margin)
        if believed is None or learned is None:
            return
        self._learning.learn(
            pose, ground.terrain_class, believed, learned, pitch, "dug in climbing", drive_on=False
        )
        self.safety.progress_learned(f"learned {believed.name}'s traction; planning again")

    def _safety_inputs(self, now: int, pose: PoseEstimate | None) -> SafetyInputs:
        wheels = self._wheels
        attitude = self._attitude
        last_tick = self._last_tick_ns
        # Positional, in SafetyInputs' field order (keywords cost a dict per tick): now, tick gap, wheel
        # status times, bus off, send failing since, estimator healthy, last GPS, last heartbeat, last
        # ground contact, sent speed, sent at, measured speed, roll/pitch and when it arrived, lateral
        # accel, position, battery, then per wheel: commands, speeds, currents.
        return SafetyInputs(
            now,
            None if last_tick is None else now - last_tick,
            wheels.status_ns,
            self._can.state is CanLinkState.BUS_OFF,
            self._send_failing_since_ns,
            pose is not None and pose.healthy,
            self._last_gps_ns,
            self._mavlink.last_heartbeat_ns,
            self._ground_contact_ns(),
            self._sent_speed_mps,
            self._sent_at_ns,
            None if pose is None else pose.speed,
            None if attitude is None else (attitude.roll_rad, attitude.pitch_rad),
            None if attitude is None else attitude.t_ns,
            0.0 if pose is None else pose.speed * pose.yaw_rate,
            None if pose is None else (pose.x, pose.y),
            wheels.battery_v,
            self._sent_wheels_mps,
            wheels.judged_speeds_mps,
            wheels.judged_currents_a,
        )

    def _ground_contact_ns(self) -> int | None:
        """The newest sign of the ground station: its last command, or its command source's last contact."""
        source_contact = None if self._commands is None else self._commands.last_contact_ns
        if source_contact is None or self._last_ground_ns is None:
            return self._last_ground_ns if source_contact is None else source_contact
        return max(self._last_ground_ns, source_contact)

    def _read_commands(self) -> None:
        if self._commands is None:
            return
        for command in self._commands.poll():
            self._last_ground_ns = command.received_ns  # a sign of the ground station, for its failsafe
            self.take_command(command)

    def take_command(self, command: RoverCommand) -> None:
        """A goal, e-stop or resume from outside the links (the ground station over Zenoh, ``rover run
        --goal``): recorded on ground/commands as taken, the stack's input that a replay (hil.replay) gives
        back, then acted on."""
        now = self._clock.now_ns()
        self._sink.publish(topics.GROUND_COMMANDS, now, command_record(now, command))
        who = "ground station" if command.origin == "zenoh" else command.origin
        if command.kind == "estop":
            self.estop(who)
        elif command.kind == "resume":
            self.resume(who)
        elif command.x is not None and command.y is not None:
            self.set_goal(command.x, command.y)

    def _read_obstacles(self, now: int, source: ObstacleSource) -> None:
        seen = source.poll()
        if not seen:
            return
        self.guidance.observe(seen)
        self._sink.publish(topics.PERCEPTION_OBSTACLES, now, obstacles_record(now, seen))

    def _read_ground_station(self) -> None:
        link = self._ground_station
        if link is None:
            return
        for reading in link.poll():
            if isinstance(reading, GoalRequest):
                self._mission_driver.goal_from_ground_station(reading)
            elif isinstance(reading, StopRequest):
                self.estop(f"MAVLink {reading.source} from system {reading.sysid}")
            elif isinstance(reading, MissionMessage):
                self._mission_driver.take_message(link, reading)

    def _read_links(self, now: int, *, stop_at_pacing: bool = False) -> None:
        """Read and fuse every link, the pacing sensor's link first; with ``stop_at_pacing``, return as
        soon as a pacing sample is in (the tick it starts should not wait for the other links: they are
        read again within a millisecond)."""
        self._pacing_rx_ns = None
        if self._ground_station is not None:
            self._read_ground_station()
        first, second = self._link_readers
        first(now)
        if stop_at_pacing and self._pacing_rx_ns is not None:
            return
        second(now)

    def _read_mavlink(self, now: int) -> None:
        del now  # each reading carries its own receive time
        beams: list[RangeBeam] = []
        for reading in self._mavlink.poll():
            # Most frequent first: an IMU sample every tick, attitude and GPS a few times a second.
            if isinstance(reading, ImuSample):
                if self._pacing == "imu":
                    self._pacing_rx_ns = reading.t_ns
                gz = reading.gyro_xyz_rps[2]
                ax, ay, _ = reading.accel_xyz_mps2
                self.estimator.on_imu(reading.t_ns, gz, ax, ay)
            elif isinstance(reading, GpsFix):
                if self._pacing == "gps":
                    self._pacing_rx_ns = reading.t_ns
                if reading.fix_type >= MIN_GPS_FIX_TYPE:
                    self._last_gps_ns = reading.t_ns
                    self._learning.gps_velocity(reading.t_ns, reading.speed_mps, reading.course_rad)
                eph_m = reading.eph_m
                self.estimator.on_gps(
                    reading.t_ns,
                    reading.lat_deg,
                    reading.lon_deg,
                    reading.alt_m,
                    reading.fix_type,
                    # The link's NaN is MAVLink's "unknown" (UINT16_MAX); the estimator's is None (it then
                    # takes its configured GPS noise). A NaN would be refused as a bad accuracy: every fix.
                    None if math.isnan(eph_m) else eph_m,
                    reading.satellites,
                )
            elif isinstance(reading, GoalRequest):
                self._mission_driver.goal_from_ground_station(reading)
            elif isinstance(reading, StopRequest):
                self.estop(f"MAVLink {reading.source} from system {reading.sysid}")
            elif isinstance(reading, ObstacleScan):
                self._take_scan(reading)
            elif isinstance(reading, RangeBeam):
                beams.append(reading)
            elif isinstance(reading, AttitudeSample):
                if math.isfinite(reading.roll_rad) and math.isfinite(reading.pitch_rad):
                    self._attitude = reading
                else:
                    self._reject_tilt(reading)
                self.estimator.on_attitude(
                    reading.t_ns, reading.yaw_rad, AHRS_HEADING_STD_RAD, pitch_rad=reading.pitch_rad
                )
            elif isinstance(reading, MissionMessage):
                self._mission_driver.take_message(self._mavlink, reading)
        if beams:
            self._take_beams(beams)

    def _take_scan(self, scan: ObstacleScan) -> None:
        """A range scan to the tracker, placed from the pose estimate as it stands now; before the rover
        knows where it is and which way it faces, the tracker only counts it (``scans_without_pose``)."""
        pose = self.estimator.pose()
        self._scans_in = True
        self._scan_watch.scan(scan.t_ns)
        # The heading is needed in either frame: the dead-reckoned frame integrates speed along it.
        if pose is None or not pose.healthy or not pose.heading_known:
            self.scan_tracker.add(scan, None)
            return
        # Tracked in the dead-reckoned frame (navigator.odometry_frame), reported on the map.
        frame = self._odometry_frame
        frame.advance(scan.t_ns, pose.speed, pose.yaw, (pose.x, pose.y))
        self.scan_tracker.add(scan, (frame.x, frame.y, pose.yaw), frame.offset())

    def _take_beams(self, beams: list[RangeBeam]) -> None:
        """One read's rangefinder readings to the tracker as one partial scan (``ScanTracker.add_beams``),
        placed from the pose estimate as it stands now, as a scan is."""
        for beam in beams:
            self._rangefinder_watch.heard(beam.sensor_id, beam.t_ns)
        pose = self.estimator.pose()
        self._scans_in = True
        if pose is None or not pose.healthy or not pose.heading_known:
            self.scan_tracker.add_beams(beams, None)
            return
        frame = self._odometry_frame
        frame.advance(beams[-1].t_ns, pose.speed, pose.yaw, (pose.x, pose.y))
        self.scan_tracker.add_beams(beams, (frame.x, frame.y, pose.yaw), frame.offset())

    def _reject_tilt(self, reading: AttitudeSample) -> None:
        """An AHRS attitude without a usable roll or pitch (NaN, inf): the tip-over check would read no
        margin at all from it (NaN: never trips, so one such sample hid a tipped rover) or an infinite tilt
        (a false trip). It is counted and logged, and the last usable attitude stands, for
        ``[safety] attitude_timeout_s`` from its arrival: then ``attitude_lost`` holds the rover. Its yaw
        still goes to the estimator, which judges that on its own."""
        self.attitude_rejected += 1
        count = self.attitude_rejected
        if count == 1 or count % _LOG_EVERY == 0:
            _log.warning(
                "AHRS attitude rejected (%d so far): roll %s, pitch %s rad is not a tilt the tip-over check "
                "can use; it judges on the last usable attitude",
                count,
                reading.roll_rad,
                reading.pitch_rad,
            )

    def _read_can(self, now: int) -> None:
        can_read_ns = self._clock.now_ns()
        if self._can.poll():
            # One snapshot per poll: the readings change only when frames arrive, and the start-up checks
            # and the safety inputs of this tick read the same snapshot.
            self._wheels = wheels = WheelSnapshot.of(self._can.wheel_status())
            if wheels.heard:
                if self._pacing == "wheels":
                    self._pacing_rx_ns = can_read_ns
                # All six: disagreement between the wheels of one side is a slip signal to the estimator.
                self.estimator.on_wheel_speeds(now, wheels.judged_speeds_mps)  # all heard: as reported


def _limit_reason(guidance: GuidanceCommand | GuidanceOutput, mode: SafetyMode, scale: float) -> str:
    if mode is not SafetyMode.DRIVING and mode is not SafetyMode.IDLE:
        return f"safety {mode.value.lower()}"
    if 0.0 < scale < 1.0:
        return "battery low"
    return guidance.speed_limit_reason
