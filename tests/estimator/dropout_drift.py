"""A 30 s GPS dropout on rocky ground in lockstep HIL, measured from the MCAP.

Used by ``test_hil_faults.py`` and runnable on its own to print the figures per seed:
``.venv/bin/python -m tests.estimator.dropout_drift [SEED ...]``.

Drift is how far the estimate moved relative to truth during the dropout (the error vector minus the
error at the dropout's start), as a share of the distance the rover truly travelled in it. The window is
the fault's own, ``[start, end)``: the pose published at ``end`` has already fused the first returning fix,
whose 0.5 m noise is GPS error, not dead-reckoning drift.
"""

from __future__ import annotations

import math
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hil.scenario import load_scenario
from hil.trial import run_trial
from logs.reader import read_messages
from logs.settings import parse_toml
from logs.topics import ESTIMATOR_POSE, TRUTH_POSE
from navigator.config import rover_config_from_table

DATA = Path(__file__).resolve().parent / "data"
DROPOUT_START_NS = 6_000_000_000  # as in data/rocky_dropout.toml
DROPOUT_END_NS = 36_000_000_000
HEALTH_THRESHOLD_M = 0.6
# The supervisor would hold the rover after 3 s without GPS; for this measurement it keeps driving.
CONFIG = f"""
[safety]
gps_budget_s = 40.0
estimator_unhealthy_s = 40.0
[estimator]
healthy_position_std_m = {HEALTH_THRESHOLD_M}
"""


@dataclass(frozen=True)
class DropoutResult:
    distance_m: float
    drift_m: float
    unhealthy_at_ns: int | None
    std_when_unhealthy_m: float | None
    std_before_unhealthy_m: float | None

    @property
    def drift_pct(self) -> float:
        return 100.0 * self.drift_m / self.distance_m


def run_dropout(seed: int, out: Path) -> DropoutResult:
    config = rover_config_from_table(parse_toml(CONFIG, "<dropout>"))
    result = run_trial(load_scenario(DATA / "rocky_dropout.toml"), config, out, seed=seed)
    truth = {m.log_time_ns: m.message for m in read_messages(result.mcap_path, topics=[TRUTH_POSE])}
    estimate = {m.log_time_ns: m.message for m in read_messages(result.mcap_path, topics=[ESTIMATOR_POSE])}
    times = sorted(t for t in estimate if t in truth and DROPOUT_START_NS <= t < DROPOUT_END_NS)
    distance, drift, start_error = 0.0, 0.0, None
    previous = None
    unhealthy_at, std_at, std_before = None, None, None
    for t in times:
        true_xy = _xy(truth[t])
        error = np.subtract(_xy(estimate[t]), true_xy)
        if previous is not None:
            distance += math.dist(true_xy, previous)
        previous = true_xy
        start_error = error if start_error is None else start_error
        drift = max(drift, float(np.hypot(*(error - start_error))))
        std = _position_std(estimate[t]["covariance"])
        if unhealthy_at is None:
            if estimate[t]["healthy"]:
                std_before = std
            else:
                unhealthy_at, std_at = t, std
    return DropoutResult(distance, drift, unhealthy_at, std_at, std_before)


def _xy(message: dict) -> tuple[float, float]:
    position = message["pose"]["position"]
    return float(position["x"]), float(position["y"])


def _position_std(covariance: list[float]) -> float:
    n = round(math.sqrt(len(covariance)))
    block = np.asarray(covariance, dtype=float).reshape(n, n)[:2, :2]
    return float(np.sqrt(np.linalg.eigvalsh(block).max()))


def main(seeds: list[int]) -> None:
    for seed in seeds:
        with tempfile.TemporaryDirectory() as out:
            r = run_dropout(seed, Path(out))
        unhealthy = "never" if r.unhealthy_at_ns is None else f"{r.unhealthy_at_ns / 1e9:.2f} s"
        print(
            f"seed {seed}: travelled {r.distance_m:.1f} m in the dropout, drift {r.drift_m:.2f} m "
            f"({r.drift_pct:.2f} %), unhealthy at {unhealthy}"
        )


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [5, 6, 7])
