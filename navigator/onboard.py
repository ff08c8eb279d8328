"""The onboard loop: links -> estimator -> planner/follower -> wheel commands, one tick at a time.

``OnboardStack.step()`` is one control tick. The same object runs on the rover (a real-time scheduler calls
``step`` at the control rate), in lockstep HIL (the trial runner calls it after advancing the simulated
clock) and in tests. It owns no clock and opens no connection: both are handed in.
"""

from __future__ import annotations

import enum
import logging
import math
from dataclasses import dataclass

import numpy as np

from estimator.estimator import Estimator
from firmware_bridge.can_link import CanLink
from firmware_bridge.mavlink_link import AttitudeSample, GpsFix, ImuSample, MavlinkLink
from logs import topics
from logs.clock import NS_PER_S, Clock
from logs.sink import MessageSink
from navigator.config import RoverConfig
from navigator.errors import PlanningError
from navigator.follower import PurePursuit
from navigator.mixing import mix_skid_steer
from navigator.planner import Path, Planner
from navigator.terrain import TerrainMap

_log = logging.getLogger(__name__)

HEARTBEAT_PERIOD_NS = NS_PER_S
# The autopilot's AHRS heading seeds the estimator; compass-aided yaw is good to a few degrees.
AHRS_HEADING_STD_RAD = math.radians(5.0)
# Readiness check before driving: the estimate must stay healthy this long (several GPS fixes averaged),
# so the first plan does not start from one noisy fix.
SETTLE_NS = 2 * NS_PER_S
LEFT_WHEELS = (0, 1, 2)
RIGHT_WHEELS = (3, 4, 5)


class Mode(enum.StrEnum):
    IDLE = "IDLE"  # no goal
    WAITING_ESTIMATE = "WAITING_ESTIMATE"  # goal set, estimator not yet healthy
    DRIVING = "DRIVING"
    ARRIVED = "ARRIVED"
    NO_PATH = "NO_PATH"  # the planner proved the goal unreachable


@dataclass(frozen=True)
class Goal:
    x: float
    y: float


class OnboardStack:
    """Estimator, planner, follower and mixer between a CAN link and a MAVLink link."""

    def __init__(
        self,
        config: RoverConfig,
        clock: Clock,
        can_link: CanLink,
        mavlink: MavlinkLink,
        sink: MessageSink,
        terrain: TerrainMap,
    ) -> None:
        self._config = config
        self._clock = clock
        self._can = can_link
        self._mavlink = mavlink
        self._sink = sink
        self.estimator = Estimator(config.estimator, clock, sink)
        self.planner = Planner(
            terrain,
            config.vehicle,
            heuristic=config.planner.heuristic,
            inflation_m=config.planner.inflation_m,
        )
        self._follower = PurePursuit(config.follower)
        self.mode = Mode.IDLE
        self.goal: Goal | None = None
        self.path: Path | None = None
        self._last_heartbeat_ns: int | None = None
        self._healthy_since_ns: int | None = None
        self._closed = False

    # --- commands from outside (ground station, trial runner) ---------------------------------------
    def set_goal(self, x: float, y: float) -> None:
        self.goal = Goal(x, y)
        self.path = None
        self.mode = Mode.WAITING_ESTIMATE
        self._event("goal", "info", f"new goal ({x:.2f}, {y:.2f})")

    # --- the control tick ---------------------------------------------------------------------------
    def step(self) -> None:
        now = self._clock.now_ns()
        self._read_links(now)
        if self._last_heartbeat_ns is None or now - self._last_heartbeat_ns >= HEARTBEAT_PERIOD_NS:
            self._mavlink.send_heartbeat()
            self._last_heartbeat_ns = now

        speed, yaw_rate = 0.0, 0.0
        state = {"cte": 0.0, "limit": 0.0, "reason": "stopped"}
        pose = self.estimator.pose()
        healthy = pose is not None and pose.healthy
        if not healthy:
            self._healthy_since_ns = None
        elif self._healthy_since_ns is None:
            self._healthy_since_ns = now
        settled = self._healthy_since_ns is not None and now - self._healthy_since_ns >= SETTLE_NS
        if self.mode is Mode.WAITING_ESTIMATE and settled and pose is not None and self.goal is not None:
            self._plan(now, pose.x, pose.y)
        if self.mode is Mode.DRIVING and pose is not None and self.path is not None:
            command = self._follower.command(pose.x, pose.y, pose.yaw, pose.speed, self.path.points)
            state = {
                "cte": command.cross_track_error_m,
                "limit": command.speed_limit_mps,
                "reason": command.speed_limit_reason,
            }
            if command.arrived:
                self.mode = Mode.ARRIVED
                self._event("arrived", "info", f"goal reached at ({pose.x:.2f}, {pose.y:.2f})")
            else:
                speed, yaw_rate = command.speed_mps, command.yaw_rate_rps

        wheel_speeds = mix_skid_steer(speed, yaw_rate, self._config.vehicle)
        erpm = self._can.send_wheel_speeds(wheel_speeds)
        self._sink.publish(
            topics.WHEELS_COMMAND,
            now,
            {
                "timestamp": topics.stamp(now),
                "speed_mps": list(wheel_speeds),
                "erpm": list(erpm),
                "body_speed_mps": speed,
                "body_yaw_rate_rps": yaw_rate,
            },
        )
        self.estimator.publish_pose(now)
        goal = {"x": self.goal.x, "y": self.goal.y} if self.goal else {"x": math.nan, "y": math.nan}
        self._sink.publish(
            topics.NAVIGATOR_STATE,
            now,
            {
                "timestamp": topics.stamp(now),
                "mode": self.mode.value,
                "goal": goal,
                "cross_track_error_m": state["cte"],
                "speed_limit_mps": state["limit"],
                "speed_limit_reason": state["reason"],
                "target_speed_mps": speed,
                "target_yaw_rate_rps": yaw_rate,
            },
        )

    def close(self) -> None:
        """Stop the wheels (zero commands) and release the links; safe to call twice."""
        if self._closed:
            return
        self._closed = True
        self._can.close()
        self._mavlink.close()

    # --- internals ------------------------------------------------------------------------------------
    def _read_links(self, now: int) -> None:
        for reading in self._mavlink.poll():
            if isinstance(reading, GpsFix):
                self.estimator.on_gps(
                    reading.t_ns,
                    reading.lat_deg,
                    reading.lon_deg,
                    reading.alt_m,
                    reading.fix_type,
                    reading.eph_m,
                    reading.satellites,
                )
            elif isinstance(reading, ImuSample):
                gz = reading.gyro_xyz_rps[2]
                ax, ay, _ = reading.accel_xyz_mps2
                self.estimator.on_imu(reading.t_ns, gz, ax, ay)
            elif isinstance(reading, AttitudeSample) and not self.estimator.heading_known:
                self.estimator.set_initial_heading(reading.yaw_rad, AHRS_HEADING_STD_RAD)
        if self._can.poll():
            readings = self._can.readings()
            if all(r.last_status_ns is not None for r in readings):
                left = float(np.mean([readings[i].speed_mps for i in LEFT_WHEELS]))
                right = float(np.mean([readings[i].speed_mps for i in RIGHT_WHEELS]))
                self.estimator.on_wheels(now, left, right)

    def _plan(self, now: int, x: float, y: float) -> None:
        assert self.goal is not None
        try:
            self.path = self.planner.plan((x, y), (self.goal.x, self.goal.y))
        except PlanningError as err:
            self.mode = Mode.NO_PATH
            self._event("no_path", "error", str(err))
            return
        self.mode = Mode.DRIVING
        self._sink.publish(
            topics.NAVIGATOR_PATH,
            now,
            {
                "timestamp": topics.stamp(now),
                "frame_id": topics.ENU_FRAME,
                "poses": [topics.planar_pose(float(px), float(py), 0.0) for px, py in self.path.points],
                "cost": self.path.cost,
                "length_m": self.path.length_m,
            },
        )
        self._event("planned", "info", f"path of {self.path.length_m:.1f} m, cost {self.path.cost:.1f}")

    def _event(self, kind: str, severity: str, detail: str) -> None:
        now = self._clock.now_ns()
        _log.info("%s: %s", kind, detail)
        self._sink.publish(
            topics.SAFETY_EVENTS,
            now,
            {"timestamp": topics.stamp(now), "kind": kind, "severity": severity, "detail": detail},
        )
