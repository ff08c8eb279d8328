"""Skid-steer mixing: body speed and yaw rate <-> six wheel surface speeds (wheel order LF LM LR RF RM RR)."""

from __future__ import annotations

import math
from collections.abc import Sequence

from navigator.errors import ParameterError
from navigator.vehicle import VehicleParams


def mix_skid_steer(speed_mps: float, yaw_rate_rps: float, params: VehicleParams) -> list[float]:
    """Wheel surface speeds (m/s) for a body speed and yaw rate.

    ``left = v - w * T_eff / 2``, ``right = v + w * T_eff / 2`` with ``T_eff = track * skid_factor``. When a
    side would exceed ``max_wheel_speed_mps`` both sides are scaled by the same factor: speed and yaw rate
    shrink together, so the path curvature ``v / w`` the follower asked for is kept.
    """
    if not (math.isfinite(speed_mps) and math.isfinite(yaw_rate_rps)):
        raise ParameterError(f"mixing needs finite commands, got speed {speed_mps}, yaw rate {yaw_rate_rps}")
    half_difference = 0.5 * yaw_rate_rps * params.effective_track_m
    left = speed_mps - half_difference
    right = speed_mps + half_difference
    peak = max(abs(left), abs(right))
    if peak > params.max_wheel_speed_mps:
        scale = params.max_wheel_speed_mps / peak
        left *= scale
        right *= scale
    return [left, left, left, right, right, right]


def unmix_skid_steer(wheel_speeds: Sequence[float], params: VehicleParams) -> tuple[float, float]:
    """(speed m/s, yaw rate rad/s) from six wheel surface speeds: each side's mean, then the inverse mix."""
    if len(wheel_speeds) != 6:
        raise ParameterError(f"expected 6 wheel speeds (LF LM LR RF RM RR), got {len(wheel_speeds)}")
    if not all(math.isfinite(v) for v in wheel_speeds):
        raise ParameterError(f"wheel speeds must be finite, got {list(wheel_speeds)}")
    left = sum(wheel_speeds[:3]) / 3.0
    right = sum(wheel_speeds[3:]) / 3.0
    return 0.5 * (left + right), (right - left) / params.effective_track_m
