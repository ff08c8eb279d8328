"""Moving obstacles of a scenario; the motion itself is ``logs.obstacle_motion`` (the metrics need it too)."""

from logs.obstacle_motion import MovingObstacle

__all__ = ["MovingObstacle"]
