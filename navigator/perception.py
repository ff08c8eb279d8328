"""What the rover perceives of obstacles around it, from whatever sensor or simulator provides it.

On the rover a lidar or camera pipeline implements ``ObstacleSource``; in HIL the simulator does (only
obstacles within sensing range, static and moving). The navigator consumes observations to repair its
plan and to stop or slow for moving obstacles in its way.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from logs import topics


@dataclass(frozen=True)
class ObstacleObservation:
    """One obstacle seen at ``t_ns``: a disc in local ENU with its velocity (m/s; 0 for static ones)."""

    t_ns: int
    obstacle_id: str
    x: float
    y: float
    radius_m: float
    vx: float = 0.0
    vy: float = 0.0

    @property
    def moving(self) -> bool:
        return self.vx != 0.0 or self.vy != 0.0


def obstacles_record(now_ns: int, seen: Sequence[ObstacleObservation]) -> dict[str, object]:
    """A ``perception/obstacles`` message of ``seen`` at ``now_ns``."""
    return {
        "timestamp": topics.stamp(now_ns),
        "obstacles": [
            {"id": o.obstacle_id, "x": o.x, "y": o.y, "radius_m": o.radius_m, "vx": o.vx, "vy": o.vy}
            for o in seen
        ],
    }


class ObstacleSource(Protocol):
    def poll(self) -> list[ObstacleObservation]:
        """Observations made since the last call, oldest first (empty when nothing new was seen)."""
        ...
