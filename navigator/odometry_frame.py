"""A local frame that moves with the rover's own motion only: dead reckoning from the estimate's speed and
heading, without the position fixes' corrections.

Obstacles are tracked in it (``navigator.scan_tracker``). Placed with the fused position instead, a static
rock moved with each GPS correction of the estimate, and a cart's fitted velocity took up the estimate's
own lag: while the rover backed off from a cart crossing at 1 m/s, the cart seemed to follow it at
0.1-0.15 m/s, enough for the back-off to judge that backing further gained nothing; four of five
``scenarios/carts.toml`` seeds ended in a collision that the true pose avoided in all five. The frame shares
the map's axes (the heading estimate is smooth); it is offset from the map by ``offset()``, the fused
position minus the dead-reckoned one, which moves slowly and moves every track alike.
"""

from __future__ import annotations

import math

# Samples further apart than this (the scans stopped, or came while the estimate was unusable) are not
# dead-reckoned across: the speed and heading at the two ends say little about the path between. The
# frame moves as the fused position did instead, so the offset holds and the tracks stay put on the map.
MAX_GAP_S = 0.5


class OdometryFrame:
    """Dead reckoning on the samples given to ``advance`` (speed m/s along heading rad from east)."""

    def __init__(self) -> None:
        self._last: tuple[int, float, float] | None = None  # t_ns, speed, yaw of the previous sample
        self.x = 0.0
        self.y = 0.0
        self._offset = (0.0, 0.0)

    def advance(self, t_ns: int, speed_mps: float, yaw_rad: float, fused_xy: tuple[float, float]) -> None:
        """Move to ``t_ns`` (trapezoidal in speed and heading from the previous sample) and note the fused
        position of that moment; the first sample puts the frame's origin where the fused position is."""
        last = self._last
        dt_s = 0.0 if last is None else max(0.0, (t_ns - last[0]) * 1e-9)
        if last is None:
            self.x, self.y = fused_xy
        elif dt_s > MAX_GAP_S:
            self.x, self.y = fused_xy[0] - self._offset[0], fused_xy[1] - self._offset[1]
        else:
            _, last_speed, last_yaw = last
            # The mean heading through the wrap at +-pi, not the mean of the two numbers.
            yaw = last_yaw + 0.5 * math.remainder(yaw_rad - last_yaw, math.tau)
            step = 0.5 * (last_speed + speed_mps) * dt_s
            self.x += step * math.cos(yaw)
            self.y += step * math.sin(yaw)
        self._last = (t_ns, speed_mps, yaw_rad)
        self._offset = (fused_xy[0] - self.x, fused_xy[1] - self.y)

    def offset(self) -> tuple[float, float]:
        """Map position minus frame position, as of the last ``advance``."""
        return self._offset
