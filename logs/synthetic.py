"""A synthetic trial recording with the lockstep trial's topics, message shapes and rates, for the
benchmark ("report time for a 10-minute trial") and for report tests that must not depend on the simulator.

Per simulated second, as the small lockstep trial records: 50 truth poses, estimates, navigator states,
wheel status/command and stability messages, ~105 innovations and ~720 CAN frames. The rover drives a
straight planned line at 0.8 m/s with a slow sideways wobble of ``wobble_m``, so the cross-track error
and path accuracy are known in closed form. Deterministic: a seeded generator adds the estimate noise.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator

import numpy as np

from logs.sink import Message, MessageSink
from logs.topics import (
    CAN_FRAMES,
    ESTIMATOR_INNOVATIONS,
    ESTIMATOR_POSE,
    NAVIGATOR_PATH,
    NAVIGATOR_STATE,
    TRUTH_POSE,
    TRUTH_STABILITY,
    WHEELS_COMMAND,
    WHEELS_STATUS,
    planar_pose,
    stamp,
)

CONTROL_PERIOD_NS = 20_000_000
SPEED_MPS = 0.8
CAN_FRAMES_PER_TICK = 14  # ~720 per second at 50 Hz, as the lockstep trial
WOBBLE_PERIOD_S = 20.0

Record = tuple[str, int, Message]


def synthetic_trial(
    duration_s: float, *, wobble_m: float = 0.3, seed: int = 1, terrain: str = "rocky"
) -> Iterator[Record]:
    """(topic, log_time_ns, message) in log-time order; the planned path is the x axis."""
    rng = np.random.default_rng(seed)
    length = SPEED_MPS * duration_s
    path = {
        "timestamp": stamp(0),
        "frame_id": "enu",
        "poses": [planar_pose(x, 0.0, 0.0) for x in np.linspace(0.0, length, 50).tolist()],
        "cost": length,
        "length_m": length,
    }
    yield NAVIGATOR_PATH, 0, path
    ticks = int(duration_s * 1e9) // CONTROL_PERIOD_NS
    for tick in range(1, ticks + 1):
        t = tick * CONTROL_PERIOD_NS
        s = t / 1e9
        x = SPEED_MPS * s
        y = wobble_m * math.sin(2.0 * math.pi * s / WOBBLE_PERIOD_S)
        ts = stamp(t)
        yield (
            TRUTH_POSE,
            t,
            {
                "timestamp": ts,
                "frame_id": "enu",
                "pose": planar_pose(x, y, 0.0),
                "yaw_rad": 0.0,
                "roll_rad": 0.01,
                "pitch_rad": 0.02,
                "speed_mps": SPEED_MPS,
                "lateral_speed_mps": 0.0,
                "yaw_rate_rps": 0.0,
                "terrain": terrain,
            },
        )
        ex, ey = x + float(rng.normal(0.0, 0.1)), y + float(rng.normal(0.0, 0.1))
        yield (
            ESTIMATOR_POSE,
            t,
            {
                "timestamp": ts,
                "frame_id": "enu",
                "pose": planar_pose(ex, ey, 0.0),
                "yaw_rad": 0.0,
                "speed_mps": SPEED_MPS,
                "yaw_rate_rps": 0.0,
                "state_names": ["x_m", "y_m", "yaw_rad", "speed_mps", "yaw_rate_rps"],
                "covariance": [0.01] * 25,
                "healthy": True,
            },
        )
        yield (
            NAVIGATOR_STATE,
            t,
            {
                "timestamp": ts,
                "mode": "ARRIVED" if tick == ticks else "DRIVING",
                "goal": {"x": length, "y": 0.0},
                "cross_track_error_m": y,
                "speed_limit_mps": 1.0,
                "speed_limit_reason": "terrain",
                "target_speed_mps": SPEED_MPS,
                "target_yaw_rate_rps": 0.0,
                "safety_mode": "IDLE" if tick == ticks else "DRIVING",
                "failsafes": [],
            },
        )
        yield (
            WHEELS_COMMAND,
            t,
            {
                "timestamp": ts,
                "speed_mps": [SPEED_MPS] * 6,
                "erpm": [1800.0] * 6,
                "body_speed_mps": SPEED_MPS,
                "body_yaw_rate_rps": 0.0,
            },
        )
        yield WHEELS_STATUS, t, {"timestamp": ts, "wheels": [_wheel(i) for i in range(6)]}
        yield (
            TRUTH_STABILITY,
            t,
            {
                "timestamp": ts,
                "roll_rad": 0.01,
                "pitch_rad": 0.02,
                "roll_margin_rad": 0.7,
                "pitch_margin_rad": 0.8,
                "rollover": False,
            },
        )
        for sensor in ("gyro", "odometry") if tick % 10 else ("gyro", "odometry", "gps"):
            yield (
                ESTIMATOR_INNOVATIONS,
                t,
                {
                    "timestamp": ts,
                    "sensor": sensor,
                    "innovation": [float(rng.normal())],
                    "nis": float(rng.chisquare(1)),
                    "accepted": True,
                },
            )
        for frame in range(CAN_FRAMES_PER_TICK):
            yield (
                CAN_FRAMES,
                t,
                {
                    "timestamp": ts,
                    "direction": "rx" if frame % 2 else "tx",
                    "id": 0x900 + frame,
                    "extended": True,
                    "dlc": 8,
                    "data": f"{tick:08x}{frame:08x}",
                },
            )


def _wheel(index: int) -> Message:
    return {
        "controller_id": index + 1,
        "erpm": 1800.0,
        "speed_mps": SPEED_MPS,
        "motor_current_a": 2.0,
        "input_current_a": 0.5,
        "duty": 0.3,
        "input_voltage_v": 24.0,
        "tachometer": 0.0,
    }


def write_synthetic_trial(sink: MessageSink, duration_s: float, **kwargs: object) -> int:
    """Publish a synthetic trial into ``sink``; the number of messages."""
    count = 0
    for topic, t, message in synthetic_trial(duration_s, **kwargs):  # type: ignore[arg-type]
        sink.publish(topic, t, message)
        count += 1
    return count


def synthetic_metadata(duration_s: float, terrain: str = "rocky") -> dict[str, str]:
    """The ``scenario`` metadata record the trial runner would write for the synthetic run."""
    return {
        "name": f"synthetic-{terrain}",
        "duration_s": repr(duration_s),
        "terrain_class": terrain,
        "path_tolerance_m": "0.5",
        "encounter_margin_m": "2.5",
        "obstacles_json": json.dumps([{"id": "far", "x": 0.0, "y": 50.0, "radius": 0.5}]),
    }
