"""What the estimator hands the navigator, and its ``estimator/pose`` message."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from estimator.ekf import STATE_NAMES
from logs.topics import ENU_FRAME, planar_pose, stamp


# A NamedTuple, immutable like the frozen dataclass it was but cheaper to build (a new one on every tick
# the filter changed: the dataclass's __init__, an object.__setattr__ per field, was ~1.1 us of ~0.3).
class PoseEstimate(NamedTuple):
    """The fused estimate at ``t_ns``. Equal only to itself (a tuple's ``==`` would compare the covariance
    array elementwise and fail).

    Attributes
    ----------
    x, y : float
        Position, local ENU metres.
    yaw : float
        Heading, radians CCW from east, in (-pi, pi].
    speed : float
        Forward speed, m/s.
    yaw_rate : float
        Yaw rate, rad/s.
    covariance : ndarray, shape (7, 7)
        Full state covariance, order as ``ekf.STATE_NAMES``; read-only when the estimator made it.
    healthy : bool
        Initialised and the worst-direction position std below ``healthy_position_std_m``.
    t_ns : int
        Time of the estimate, clock ns.
    heading_known : bool
        False until a heading was given or learnt from motion; until then ``yaw`` is a placeholder.
    position_std_m : float
        Worst-direction position std, metres.
    """

    x: float
    y: float
    yaw: float
    speed: float
    yaw_rate: float
    covariance: NDArray[np.float64]
    healthy: bool
    t_ns: int
    heading_known: bool
    position_std_m: float

    # Identity, as the frozen dataclass with eq=False had: never tuple equality over the covariance.
    def __eq__(self, other: object) -> bool:
        return self is other

    def __ne__(self, other: object) -> bool:
        return self is not other

    def __hash__(self) -> int:
        return object.__hash__(self)


def pose_message(pose: PoseEstimate) -> dict[str, Any]:
    """The ``estimator/pose`` message (foxglove.PoseInFrame plus our fields), see ``logs.topics``."""
    return {
        "timestamp": stamp(pose.t_ns),
        "frame_id": ENU_FRAME,
        "pose": planar_pose(pose.x, pose.y, pose.yaw),
        "yaw_rad": pose.yaw,
        "speed_mps": pose.speed,
        "yaw_rate_rps": pose.yaw_rate,
        "state_names": list(STATE_NAMES),
        # All 49 entries, every 20 ms: tolist() makes the Python floats in one C call, not 49 float() calls.
        "covariance": pose.covariance.ravel().tolist(),
        "healthy": pose.healthy,
    }
