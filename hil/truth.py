"""Ground truth from the simulator onto the truth/* topics: pose, wheels, stability, contacts."""

from __future__ import annotations

import math

from hil.battery import Battery
from hil.dynamics import DynamicsStep, RoverDynamics
from hil.scenario import Scenario
from logs import topics
from logs.sink import MessageSink


class TruthRecorder:
    """Publishes the true state at the recording rate and each contact (collision, rollover) once."""

    def __init__(self, sink: MessageSink, scenario: Scenario) -> None:
        self._sink = sink
        self._scenario = scenario
        self._in_collision = False
        self._rollover_reported = False
        self._touching_movers: set[str] = set()

    @property
    def in_collision(self) -> bool:
        """Whether the last step it saw touched an obstacle (a collision was reported and has not ended)."""
        return self._in_collision

    def on_step(
        self, now: int, body: RoverDynamics, step: DynamicsStep, battery: Battery, *, record_state: bool
    ) -> None:
        """A physics step: contacts that begin or end, and with ``record_state`` the truth/* state topics.

        Without ``record_state`` it does something only when ``step`` touches or rolled over, or
        ``in_collision``: the world skips the call otherwise."""
        if step.collided or step.rollover or self._in_collision:  # else no contact begins or ends
            self._contacts(now, body, step)
        if not record_state:
            return
        stamp = topics.stamp(now)
        publish = self._sink.publish
        # The pose from the step's fields (the body's state after the step: the same floats as its
        # properties, read as tuple fields rather than property calls).
        publish(
            topics.TRUTH_POSE,
            now,
            {
                "timestamp": stamp,
                "frame_id": topics.ENU_FRAME,
                "pose": topics.planar_pose(step.x, step.y, step.yaw, body.elevation_m),
                "yaw_rad": step.yaw,
                "roll_rad": step.roll_rad,
                "pitch_rad": step.pitch_rad,
                "speed_mps": step.speed_mps,
                "lateral_speed_mps": step.lateral_speed_mps,
                "yaw_rate_rps": step.yaw_rate_rps,
                "terrain": step.terrain_name,
            },
        )
        publish(
            topics.TRUTH_WHEELS,
            now,
            {
                "timestamp": stamp,
                # The step's per-wheel tuples hold plain floats already (DynamicsStep).
                "wheels": [
                    {"surface_speed_mps": speed, "slip": slip, "normal_force_n": normal, "current_a": current}
                    for speed, slip, normal, current in zip(
                        step.wheel_speeds_mps,
                        step.slip,
                        step.normal_forces_n,
                        step.motor_currents_a,
                        strict=True,
                    )
                ],
                "battery_voltage_v": battery.voltage_v,
                "energy_wh": battery.energy_wh,
            },
        )
        publish(
            topics.TRUTH_STABILITY,
            now,
            {
                "timestamp": stamp,
                "roll_rad": step.roll_rad,
                "pitch_rad": step.pitch_rad,
                "roll_margin_rad": step.roll_margin_rad,
                "pitch_margin_rad": step.pitch_margin_rad,
                "rollover": bool(step.rollover),
            },
        )

    def _contacts(self, now: int, body: RoverDynamics, step: DynamicsStep) -> None:
        if step.collided and not self._in_collision:
            self._publish_contact(now, "collision", self._nearest_obstacle(body.x, body.y), body)
        self._in_collision = step.collided
        if step.rollover and not self._rollover_reported:
            self._rollover_reported = True
            self._publish_contact(now, "rollover", "", body)

    def on_moving_contacts(self, now: int, touching: list[str], body: RoverDynamics) -> None:
        """The moving obstacles whose discs touch the footprint this tick (ids, in the world's order): a
        contact is reported once, when it begins; one that ended may be reported again when it begins anew.
        """
        movers = self._touching_movers
        if not touching and not movers:
            return  # the usual tick: nothing touches, nothing did
        for obstacle_id in touching:
            if obstacle_id not in movers:
                movers.add(obstacle_id)
                self._publish_contact(now, "collision", obstacle_id, body)
        movers.intersection_update(touching)

    def _publish_contact(self, now: int, kind: str, obstacle_id: str, body: RoverDynamics) -> None:
        self._sink.publish(
            topics.TRUTH_CONTACTS,
            now,
            {
                "timestamp": topics.stamp(now),
                "kind": kind,
                "obstacle_id": obstacle_id,
                "x": body.x,
                "y": body.y,
            },
        )

    def _nearest_obstacle(self, x: float, y: float) -> str:
        """The scenario obstacle whose edge is closest, or "terrain" (map walls, map boundary)."""
        best_id, best_gap = "terrain", math.inf
        for obstacle in self._scenario.obstacles:
            gap = math.hypot(obstacle.x - x, obstacle.y - y) - obstacle.radius_m
            if gap < best_gap:
                best_id, best_gap = obstacle.id, gap
        reach = 1.5 * max(1.0, self._scenario.terrain.resolution_m)
        return best_id if best_gap < reach else "terrain"
