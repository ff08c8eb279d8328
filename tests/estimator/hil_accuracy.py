"""Estimator accuracy read back from a HIL recording: estimate vs ground truth at the same instants."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from logs.reader import read_messages
from logs.topics import ESTIMATOR_POSE, TRUTH_POSE


@dataclass(frozen=True)
class PoseErrors:
    """Errors of every recorded estimate that has a truth sample at the same stamp (m, degrees)."""

    t_s: np.ndarray
    position_m: np.ndarray
    heading_deg: np.ndarray

    def rmse(self, after_s: float = 0.0) -> tuple[float, float]:
        keep = self.t_s >= after_s
        return (
            float(np.sqrt(np.mean(self.position_m[keep] ** 2))),
            float(np.sqrt(np.mean(self.heading_deg[keep] ** 2))),
        )


def _stamp_ns(message: dict) -> int:
    stamp = message["timestamp"]
    return int(stamp["sec"]) * 1_000_000_000 + int(stamp["nsec"])


def pose_errors(mcap_path: Path) -> PoseErrors:
    truth: dict[int, tuple[float, float, float]] = {}
    estimates: list[tuple[int, float, float, float]] = []
    for record in read_messages(mcap_path, topics=[TRUTH_POSE, ESTIMATOR_POSE]):
        m = record.message
        position = m["pose"]["position"]
        row = (float(position["x"]), float(position["y"]), float(m["yaw_rad"]))
        if record.topic == TRUTH_POSE:
            truth[_stamp_ns(m)] = row
        else:
            estimates.append((_stamp_ns(m), *row))
    rows = []
    for t_ns, x, y, yaw in estimates:
        true = truth.get(t_ns)
        if true is None:
            continue
        heading = math.degrees(math.remainder(yaw - true[2], 2.0 * math.pi))
        rows.append((t_ns * 1e-9, math.hypot(x - true[0], y - true[1]), heading))
    if not rows:
        raise AssertionError(f"{mcap_path}: no estimate shares a stamp with the truth")
    a = np.array(rows)
    return PoseErrors(a[:, 0], a[:, 1], a[:, 2])
