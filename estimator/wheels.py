"""Six wheel speeds -> skid-steer body motion, and how much the wheels of one side disagree.

Wheel order is the bus order used everywhere: left front, left middle, left rear, right front, right
middle, right rear. On firm ground the three wheels of a side turn at the same speed (they share the
ground speed of that side); a wheel that spins faster or stalls is slipping or lifted, so the spread within
a side is a slip signal the gyro cannot give (it sees no yaw when both sides slip alike).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

WHEEL_COUNT = 6
LEFT = (0, 1, 2)
RIGHT = (3, 4, 5)


# A NamedTuple, immutable like a frozen dataclass but cheaper to build (once per control tick: the
# dataclass's __init__, an object.__setattr__ per field, was a measurable share of the tick).
class BodyMotion(NamedTuple):
    """Body speed (m/s), yaw rate (rad/s) and the largest within-side wheel-speed spread (m/s)."""

    speed_mps: float
    yaw_rate_rps: float
    side_spread_mps: float


def side_speeds(left_mps: float, right_mps: float, track_m: float, skid_factor: float) -> BodyMotion:
    """Skid-steer kinematics: v = (l + r) / 2, yaw rate = (r - l) / (track * skid factor)."""
    return BodyMotion(*_body(left_mps, right_mps, track_m, skid_factor), 0.0)


def six_wheels(speeds_mps: Sequence[float], track_m: float, skid_factor: float) -> BodyMotion:
    """Body motion from six wheel surface speeds (m/s), in wheel order (see the module docstring)."""
    if len(speeds_mps) != WHEEL_COUNT:
        raise ValueError(f"need {WHEEL_COUNT} wheel speeds, got {len(speeds_mps)}")
    # Unpacked in wheel order (LEFT, RIGHT); sums from 0 in wheel order, as sum() over each side's list.
    left_front, left_middle, left_rear, right_front, right_middle, right_rear = speeds_mps
    left = (left_front, left_middle, left_rear)
    right = (right_front, right_middle, right_rear)
    speed, yaw_rate = _body(sum(left) / 3.0, sum(right) / 3.0, track_m, skid_factor)
    spread = max(max(left) - min(left), max(right) - min(right))
    return BodyMotion(speed, yaw_rate, spread)


def _body(left_mps: float, right_mps: float, track_m: float, skid_factor: float) -> tuple[float, float]:
    """(speed m/s, yaw rate rad/s) of the sides' speeds; one BodyMotion per sample is built from it."""
    return 0.5 * (left_mps + right_mps), (right_mps - left_mps) / (track_m * skid_factor)
