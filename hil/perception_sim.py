"""Simulated obstacle perception: what a range-limited sensor on the rover sees of the true obstacles.

Implements ``navigator.perception.ObstacleSource``. At ``rate_hz`` (on the clock's schedule) it reports
every static and moving obstacle whose nearest edge lies within ``range_m`` of the rover's true position,
each with its true velocity (zero for static ones) plus optional position noise from a seeded generator.
Moving obstacles move on the world's time: seconds since ``epoch_ns`` on the clock (the world's start), so
a cart with ``start_s = 600`` waits 600 s after the world started, whatever the clock read then (the real-time
peer's monotonic clock counts from the machine's boot).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from hil.moving_obstacles import MovingObstacle
from hil.scenario import Obstacle
from logs.clock import Clock, seconds, to_ns
from navigator.perception import ObstacleObservation


class PerceptionSim:
    """Obstacles within ``range_m`` of the rover, reported at ``rate_hz``; an ``ObstacleSource``."""

    def __init__(
        self,
        clock: Clock,
        rover_xy: Callable[[], tuple[float, float]],
        static: Sequence[Obstacle],
        moving: Sequence[MovingObstacle],
        rng: np.random.Generator,
        *,
        range_m: float = 8.0,
        rate_hz: float = 10.0,
        noise_m: float = 0.0,
        epoch_ns: int | None = None,
    ) -> None:
        """``epoch_ns``: the world's start on ``clock``, time zero of the moving obstacles (default: now)."""
        if not (math.isfinite(range_m) and range_m > 0.0):
            raise ValueError(f"perception range_m must be > 0, got {range_m}")
        if not (math.isfinite(rate_hz) and rate_hz > 0.0):
            raise ValueError(f"perception rate_hz must be > 0, got {rate_hz}")
        self._clock = clock
        self._rover_xy = rover_xy
        # As poll's candidates: (id, x, y, radius, vx, vy), built once (static obstacles do not change).
        self._static_candidates = [(o.id, o.x, o.y, o.radius_m, 0.0, 0.0) for o in static]
        self._moving = tuple(moving)
        self._rng = rng
        self._range_m = range_m
        self._period_ns = to_ns(1.0 / rate_hz)
        self._noise_m = noise_m
        self._next_ns = clock.now_ns()
        # Time zero of the moving obstacles; the world moves it when it holds and starts its scenario.
        self.epoch_ns = self._next_ns if epoch_ns is None else epoch_ns

    def moving_states(self, t_ns: int) -> list[tuple[MovingObstacle, tuple[float, float, float, float]]]:
        """Each moving obstacle's (x, y, vx, vy) at the clock reading ``t_ns``; it moves from the epoch."""
        t_s = seconds(t_ns - self.epoch_ns)
        return [(m, m.state_at(t_s)) for m in self._moving]

    def obstacles_at(self, t_ns: int) -> list[tuple[str, float, float, float, float, float]]:
        """Every obstacle, static then moving, as (id, x, y, radius, vx, vy) at the clock reading ``t_ns``."""
        return self._static_candidates + [
            (m.id, x, y, m.radius_m, vx, vy) for m, (x, y, vx, vy) in self.moving_states(t_ns)
        ]

    def poll(self) -> list[ObstacleObservation]:
        now = self._clock.now_ns()
        if now < self._next_ns:
            return []
        self._next_ns = max(self._next_ns + self._period_ns, now + 1)
        rx, ry = self._rover_xy()
        candidates = self.obstacles_at(now)
        # One draw pair per candidate, seen or not: the noise stream does not depend on the path. All pairs
        # in one call: the generator fills them in order, so the same numbers as a call per pair.
        noise = (self._rng.normal(0.0, 1.0, (len(candidates), 2)) * self._noise_m).tolist()
        seen: list[ObstacleObservation] = []
        for (obstacle_id, x, y, radius, vx, vy), (noise_x, noise_y) in zip(candidates, noise, strict=True):
            if math.hypot(x - rx, y - ry) - radius > self._range_m:
                continue
            seen.append(ObstacleObservation(now, obstacle_id, x + noise_x, y + noise_y, radius, vx=vx, vy=vy))
        return seen
