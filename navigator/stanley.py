"""Stanley path following for a skid-steer rover (Hoffmann et al., "Autonomous Automobile Trajectory
Tracking for Off-Road Driving", 2007), adapted from a steering angle to a yaw rate.

The Stanley law turns the heading toward ``psi_e + atan(k e / (v + v_s))``: the path's heading error plus a
correction that closes the cross-track error ``e`` faster at low speed. A skid-steer rover has no steering
angle, so the correction ``delta`` becomes a yaw rate that closes it in ``heading_time_constant_s``;
the curvature handed to the speed limits is that yaw rate over the speed.
"""

from __future__ import annotations

import math

import numpy as np

from navigator.follower import PurePursuit, wrap_angle


class Stanley(PurePursuit):
    """Same bookkeeping, speed limits and arrival test as ``PurePursuit``; only the steering law differs."""

    def _steer(
        self,
        points: np.ndarray,
        x: float,
        y: float,
        yaw: float,
        speed: float,
        projection: float,
        cross_track: float,
        lookahead: float,
    ) -> tuple[float, float]:
        cfg = self.config
        if len(points) < 2:
            return wrap_angle(math.atan2(points[-1][1] - y, points[-1][0] - x) - yaw), 0.0
        # The path heading at a short preview ahead of the projection (the front axle in Stanley's car).
        ahead = self._point_at(projection + 0.25 * lookahead + 1e-3)
        behind = self._point_at(max(projection - 1e-3, 0.0))
        path_heading = math.atan2(ahead[1] - behind[1], ahead[0] - behind[0])
        heading_error = wrap_angle(path_heading - yaw)
        # cross_track > 0: the rover is left of the path, so steer right (negative).
        delta = heading_error - math.atan(
            cfg.stanley_gain * cross_track / (abs(speed) + cfg.stanley_softening_mps)
        )
        delta = wrap_angle(delta)
        yaw_rate = delta / cfg.heading_time_constant_s
        # The curvature at a nominal speed; the speed limits then scale speed and yaw rate together.
        nominal = max(abs(speed), cfg.min_speed_mps, 0.2)
        return delta, yaw_rate / nominal
