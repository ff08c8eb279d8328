"""An estimator driven by the simulated rover (``rover_sim``), with its errors against truth at every step."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from estimator.config import EstimatorConfig
from estimator.estimator import Estimator
from estimator.geodesy import Datum, to_enu
from estimator.pose import PoseEstimate
from logs.clock import SimClock
from logs.sink import MemorySink
from tests.estimator.rover_sim import Sample, Truth, feed, simulate

SIM_DATUM = Datum(47.3769, 8.5417, 408.0)
S = 1_000_000_000


@dataclass(frozen=True)
class Step:
    """One simulated step: truth (in the estimator's ENU frame) and the estimate at the same instant."""

    truth: Truth
    true_x: float
    true_y: float
    pose: PoseEstimate

    @property
    def t_s(self) -> float:
        return self.truth.t_ns / S

    @property
    def position_error_m(self) -> float:
        return math.hypot(self.pose.x - self.true_x, self.pose.y - self.true_y)

    @property
    def yaw_error_rad(self) -> float:
        return math.remainder(self.pose.yaw - self.truth.yaw, 2 * math.pi)


class Run:
    """An estimator fed by the simulated rover, with the errors it made at every step."""

    def __init__(self, config: EstimatorConfig | None = None) -> None:
        self.clock = SimClock()
        self.sink = MemorySink()
        self.estimator = Estimator(config or EstimatorConfig(), self.clock, self.sink)
        self.errors: list[tuple[float, float, float]] = []  # (t_s, position error m, yaw error deg)
        self.steps: list[Step] = []

    def drive(
        self,
        seed: int,
        seconds: float,
        tamper: Callable[[Sample], Sample] = lambda s: s,
        on_step: Callable[[Truth], None] = lambda t: None,
        **sim_args: Any,
    ) -> None:
        rng = np.random.default_rng(seed)
        for truth, samples in simulate(rng, SIM_DATUM, seconds, **sim_args):
            self.clock.advance(truth.t_ns - self.clock.now_ns())
            feed(self.estimator, [tamper(s) for s in samples])
            pose = self.estimator.pose(truth.t_ns)
            if pose is None:
                continue
            # The estimator may have taken its datum from the first fix: compare in its frame. The two
            # datums are metres apart, so the frames differ by a shift (their rotation is ~1e-7 rad).
            datum = self.estimator.datum
            assert datum is not None
            ox, oy, _ = to_enu(datum, SIM_DATUM.lat_deg, SIM_DATUM.lon_deg, SIM_DATUM.alt_m)
            step = Step(truth, truth.x + ox, truth.y + oy, pose)
            self.steps.append(step)
            self.errors.append((step.t_s, step.position_error_m, math.degrees(step.yaw_error_rad)))
            on_step(truth)

    def rmse_after(self, t_s: float) -> tuple[float, float]:
        e = np.array([row for row in self.errors if row[0] >= t_s])
        return float(np.sqrt(np.mean(e[:, 1] ** 2))), float(np.sqrt(np.mean(e[:, 2] ** 2)))
