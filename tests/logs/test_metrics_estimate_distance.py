"""Distance driven from an estimate: its GPS jitter must not count as travel (docs/metrics.md)."""

from __future__ import annotations

import io

import numpy as np
import pytest

from logs.clock import to_ns
from logs.metrics import compute_metrics
from logs.recorder import McapRecorder
from logs.topics import ESTIMATOR_POSE, WHEELS_STATUS, planar_pose, stamp

RATE_HZ = 50.0
STANDSTILL_S = 2.0
DRIVE_S = 10.0
SPEED_MPS = 1.0
JITTER_M = 0.15  # per axis, like the estimate of a rover with 0.5 m GPS noise


def _estimate_only_run(seed: int = 4) -> bytes:
    """2 s standing at the origin, then 10 m east at 1 m/s; the estimated position jitters, its speed
    state does not (the estimator knows the wheels stand still)."""
    rng = np.random.default_rng(seed)
    buffer = io.BytesIO()
    with McapRecorder(buffer) as recorder:
        samples = int((STANDSTILL_S + DRIVE_S) * RATE_HZ) + 1
        for i in range(samples):
            t_s = i / RATE_HZ
            moving = t_s > STANDSTILL_S
            x = SPEED_MPS * (t_s - STANDSTILL_S) if moving else 0.0
            jitter = rng.normal(0.0, JITTER_M, 2)
            t = to_ns(t_s)
            pose = planar_pose(x + jitter[0], jitter[1], 0.0)
            speed = SPEED_MPS if moving else 0.0
            recorder.publish(
                ESTIMATOR_POSE,
                t,
                {"timestamp": stamp(t), "frame_id": "enu", "pose": pose, "speed_mps": speed},
            )
            wheel = {"input_voltage_v": 24.0, "input_current_a": 1.0}
            recorder.publish(WHEELS_STATUS, t, {"timestamp": stamp(t), "wheels": [dict(wheel)] * 6})
    return buffer.getvalue()


def test_the_estimate_jitter_is_not_counted_as_distance_driven() -> None:
    metrics = compute_metrics(io.BytesIO(_estimate_only_run()))
    assert metrics.trajectory_topic == ESTIMATOR_POSE
    # 10 m driven (the trapezoid over the step from 0 to 1 m/s adds half a sample: 0.01 m)
    assert metrics.distance_m == pytest.approx(SPEED_MPS * DRIVE_S, abs=0.02)
    # energy per metre divides by the same distance: 6 x 24 W over 12 s / 10 m
    assert metrics.energy_wh is not None
    assert metrics.energy_wh_per_m == pytest.approx(metrics.energy_wh / (SPEED_MPS * DRIVE_S), rel=2e-3)
