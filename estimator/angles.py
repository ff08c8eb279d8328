"""Angle wrapping, shared by the filter and its front end."""

from __future__ import annotations

import math

_TWO_PI = 2.0 * math.pi


def wrap_angle(angle_rad: float) -> float:
    """Wrap to (-pi, pi]; ``math.remainder`` gives [-pi, pi], so -pi is folded onto +pi."""
    wrapped = math.remainder(angle_rad, _TWO_PI)
    return math.pi if wrapped == -math.pi else wrapped
