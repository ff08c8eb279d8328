"""Moving obstacles: discs that walk a polyline of waypoints back and forth at a constant speed.

The position is a closed-form function of the time since the world's start (no state, no randomness), so
lockstep runs stay identical, the real-time peer agrees with lockstep about where an obstacle was at any
instant of its trial, and the trial metrics (``logs.metrics``) find it again from the recording's metadata
alone (the scenario, and the world's start on the log's clock: ``logs.scenario_record``). It lives in
``logs`` because both the simulator (``hil``) and the metrics need it and ``logs`` is the layer both may
import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class MovingObstacle:
    id: str
    radius_m: float
    waypoints: tuple[tuple[float, float], ...]  # at least two
    speed_mps: float
    start_s: float = 0.0  # it waits at the first waypoint until then (s from the world's start)

    def _legs(self) -> list[float]:
        return [math.dist(a, b) for a, b in zip(self.waypoints, self.waypoints[1:], strict=False)]

    def state_at(self, t_s: float) -> tuple[float, float, float, float]:
        """(x, y, vx, vy) ``t_s`` seconds after the world's start: out along the waypoints, back, and again
        (ping-pong)."""
        legs = self._legs()
        length = sum(legs)
        moving_s = t_s - self.start_s
        if moving_s <= 0.0 or length <= 0.0 or self.speed_mps <= 0.0:
            x, y = self.waypoints[0]
            return x, y, 0.0, 0.0
        travelled = (moving_s * self.speed_mps) % (2.0 * length)
        forward = travelled <= length
        s = travelled if forward else 2.0 * length - travelled
        direction = 1.0 if forward else -1.0
        for (ax, ay), (bx, by), leg in zip(self.waypoints, self.waypoints[1:], legs, strict=False):
            if leg > 0.0 and s <= leg:
                f = s / leg
                vx = direction * self.speed_mps * (bx - ax) / leg
                vy = direction * self.speed_mps * (by - ay) / leg
                return ax + f * (bx - ax), ay + f * (by - ay), vx, vy
            s -= leg
        x, y = self.waypoints[-1]
        return x, y, 0.0, 0.0
