"""Where a range sensor sits on the rover: its offset from the pose's reference point, and which way it faces.

The estimator's pose is of the rover's reference point (``x``, ``y`` ENU m, ``yaw`` rad from east); a lidar
sits on a mast somewhere else, usually at the front, sometimes turned. Its rays start where it is, and a
body-frame scan counts its angles from the sensor's own forward direction (a driver reports what the
sensor measures; ArduPilot adds its ``PRXn_YAW_CORR`` to OBSTACLE_DISTANCE angles the same way, counted
clockwise): both must be known to put a return on the map. ``navigator.scan_clusters`` applies the mount
to the stack's scans, ``hil.lidar_sim`` to the simulated lidar's rays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class SensorMount:
    """``forward_m``, ``left_m``: the sensor's position in the rover's body frame (forward-left-up, m from
    the reference point); ``yaw_rad``: its forward direction from the rover's, counter-clockwise."""

    forward_m: float = 0.0
    left_m: float = 0.0
    yaw_rad: float = 0.0

    def origin(self, x: float, y: float, yaw: float) -> tuple[float, float]:
        """Where the sensor is (ENU m) with the rover's reference point at ``x``, ``y`` facing ``yaw``."""
        if self.forward_m == 0.0 and self.left_m == 0.0:
            # At the centre: the pose itself, bit for bit (a centre-mounted run records what it did before).
            return x, y
        cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
        return (
            x + self.forward_m * cos_yaw - self.left_m * sin_yaw,
            y + self.forward_m * sin_yaw + self.left_m * cos_yaw,
        )

    def facing(self, yaw: float) -> float:
        """The sensor's forward direction (rad from east) with the rover facing ``yaw``."""
        return yaw + self.yaw_rad


AT_CENTRE = SensorMount()
