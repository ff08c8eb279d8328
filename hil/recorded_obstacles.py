"""Perceived obstacles read back from a recording, as an ``ObstacleSource`` for a replay (``hil.replay``).

In a lockstep trial with "objects" perception the simulator hands the onboard stack its observations in
process, and the stack records each batch on ``perception/obstacles`` at the tick that read it, every
observation stamped with that tick's time. Those records are the stack's perception input, so a replay
hands them back at the same ticks. The marks the stack puts on the same topic where it dug in
(``navigator.recovery``, ids ``dug-in-N``) are its own output, not perception: the replayed stack makes
them again, so they are left out.
"""

from __future__ import annotations

import logging
import math
from typing import Any

from navigator.perception import ObstacleObservation
from navigator.recovery import MARK_PREFIX

_log = logging.getLogger(__name__)
# Positions (m), radii (m) and speeds (m/s) beyond this are no obstacle of a rover's world: a unit mistake.
MAX_OBSTACLE_VALUE = 1.0e6


class RecordedObstacles:
    """Observations queued by the replay (``add``) until the stack's next ``poll``."""

    def __init__(self) -> None:
        self._pending: list[ObstacleObservation] = []
        self.rejected = 0  # records or obstacles in them that were not observations (logged, skipped)

    def add(self, t_ns: int, record: dict[str, Any]) -> bool:
        """One ``perception/obstacles`` record at log time ``t_ns``; a malformed entry is counted and
        logged, the rest of the record kept. False for a record of the stack's own marks alone (where it
        dug in: the replayed stack makes them again), which is no input."""
        obstacles = record.get("obstacles")
        if not isinstance(obstacles, list):
            self._reject(t_ns, f"'obstacles' is {type(obstacles).__name__}, not a list")
            return True
        own = 0
        for entry in obstacles:
            observation = _observation(t_ns, entry)
            if isinstance(observation, str):
                self._reject(t_ns, observation)
            elif observation.obstacle_id.startswith(MARK_PREFIX):
                own += 1
            else:
                self._pending.append(observation)
        return own < len(obstacles) or not obstacles

    def poll(self) -> list[ObstacleObservation]:
        seen, self._pending = self._pending, []
        return seen

    def _reject(self, t_ns: int, why: str) -> None:
        self.rejected += 1
        _log.warning("perception/obstacles record at %d ns skipped: %s", t_ns, why)


def _observation(t_ns: int, entry: object) -> ObstacleObservation | str:
    """The observation an obstacle entry holds, or why it holds none."""
    if not isinstance(entry, dict):
        return f"an obstacle is {type(entry).__name__}, not an object"
    obstacle_id = entry.get("id")
    if not isinstance(obstacle_id, str):
        return f"an obstacle's id is {obstacle_id!r}, not text"
    numbers: dict[str, float] = {}
    for key in ("x", "y", "radius_m", "vx", "vy"):
        value = entry.get(key)
        # bool is an int to Python, not a coordinate to us. The bound first: an integer of hundreds of
        # digits (JSON has them) is too large for math.isfinite's float.
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or abs(value) > MAX_OBSTACLE_VALUE
            or not math.isfinite(value)
        ):
            return f"obstacle {obstacle_id!r}: {key} is {value!r}, not a finite number within 1000 km(/s)"
        numbers[key] = float(value)
    if numbers["radius_m"] <= 0.0:
        return f"obstacle {obstacle_id!r}: radius_m {numbers['radius_m']} is not positive"
    return ObstacleObservation(
        t_ns,
        obstacle_id,
        numbers["x"],
        numbers["y"],
        numbers["radius_m"],
        vx=numbers["vx"],
        vy=numbers["vy"],
    )
