"""``rover bench estimator``: our EKF against a plain filterpy EKF of the same model, in the same run.

One *cycle* is what the rover does per 50 Hz sensor tick: predict, a gyro update and a wheel-odometry
update, plus a GPS update every 10th cycle (5 Hz). Inputs are drawn once from a seeded generator before
timing, so only the filters are measured. Three contenders:

- ``ours``: ``RoverEkf`` (hand-written numpy, gated, closed-form 1x1 / 2x2 inverses);
- ``ours_front_end``: the whole ``Estimator`` (sample checks, slip / stuck logic, geodesy for GPS,
  innovation messages to a sink that drops them): what the onboard loop really pays;
- ``filterpy``: ``FilterpyRoverEkf``, filterpy's ``ExtendedKalmanFilter`` with the same model.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from estimator.config import EstimatorConfig
from estimator.ekf import RoverEkf
from estimator.estimator import Estimator
from estimator.filterpy_peer import FilterpyRoverEkf
from estimator.geodesy import Datum, to_geodetic
from logs.clock import SimClock

STEP_NS = 20_000_000
GPS_EVERY = 10
GOAL_CYCLES_PER_S = 10_000.0
_DATUM = Datum(47.3769, 8.5417, 408.0)


class _DropSink:
    """A sink that drops every message: publishing cost is the dict building, not storage."""

    def publish(self, topic: str, log_time_ns: int, message: dict[str, Any]) -> None:
        return None


@dataclass(frozen=True)
class Inputs:
    """Pre-drawn sensor values for ``cycles`` cycles of a rover driving a gentle arc."""

    gyro: np.ndarray
    speed: np.ndarray
    yaw_rate: np.ndarray
    gps_xy: np.ndarray  # (cycles, 2), ENU m (only every GPS_EVERY-th row is used)
    gps_geodetic: list[tuple[float, float, float]]


def make_inputs(cycles: int, seed: int) -> Inputs:
    rng = np.random.default_rng(seed)
    t = np.arange(1, cycles + 1) * STEP_NS * 1e-9
    yaw = 0.1 * t
    x = np.cumsum(0.8 * np.cos(yaw) * STEP_NS * 1e-9)
    y = np.cumsum(0.8 * np.sin(yaw) * STEP_NS * 1e-9)
    gps_xy = np.column_stack([x, y]) + rng.normal(0.0, 0.5, (cycles, 2))
    geodetic = [
        to_geodetic(_DATUM, float(e), float(n), 0.0) if (k + 1) % GPS_EVERY == 0 else (0.0, 0.0, 0.0)
        for k, (e, n) in enumerate(gps_xy)
    ]
    return Inputs(
        gyro=0.1 + rng.normal(0.0, 0.005, cycles),
        speed=0.8 + rng.normal(0.0, 0.02, cycles),
        yaw_rate=0.1 + rng.normal(0.0, 0.03, cycles),
        gps_xy=gps_xy,
        gps_geodetic=geodetic,
    )


def _ours(config: EstimatorConfig) -> RoverEkf:
    ekf = RoverEkf(config)
    ekf.initialise(0.0, 0.0, 0.0, 0, 0.5, 0.1)
    return ekf


def _time(run: Callable[[], None]) -> float:
    start = time.perf_counter()
    run()
    return time.perf_counter() - start


def _best_of(repeats: int, make_run: Callable[[], Callable[[], None]]) -> float:
    """Fastest of ``repeats`` timings (s): on a shared machine the minimum is the least disturbed."""
    return min(_time(make_run()) for _ in range(repeats))


def time_cycles(inputs: Inputs, repeats: int) -> dict[str, float]:
    """Full cycles per second of each contender."""
    config = EstimatorConfig(
        datum_lat_deg=_DATUM.lat_deg, datum_lon_deg=_DATUM.lon_deg, datum_alt_m=_DATUM.alt_m
    )
    n = len(inputs.gyro)
    gyro, speed, yaw_rate = inputs.gyro.tolist(), inputs.speed.tolist(), inputs.yaw_rate.tolist()
    gps = inputs.gps_xy.tolist()

    def ours() -> Callable[[], None]:
        ekf = _ours(config)

        def run() -> None:
            for k in range(n):
                ekf.predict((k + 1) * STEP_NS)
                ekf.update_gyro(gyro[k])
                ekf.update_odometry(speed[k], yaw_rate[k], 0.05, 0.05)
                if (k + 1) % GPS_EVERY == 0:
                    ekf.update_position(gps[k][0], gps[k][1], 0.5)

        return run

    def front_end() -> Callable[[], None]:
        estimator = Estimator(config, SimClock(), _DropSink())
        estimator.set_initial_heading(0.0, 0.1)
        estimator.on_gps(0, _DATUM.lat_deg, _DATUM.lon_deg, _DATUM.alt_m, 3, 0.5, 12)
        half = 0.5 * 0.55 * 1.6

        def run() -> None:
            for k in range(n):
                t_ns = (k + 1) * STEP_NS
                estimator.on_imu(t_ns, gyro[k], 0.0, 0.0)
                estimator.on_wheels(t_ns, speed[k] - half * yaw_rate[k], speed[k] + half * yaw_rate[k])
                if (k + 1) % GPS_EVERY == 0:
                    lat, lon, alt = inputs.gps_geodetic[k]
                    estimator.on_gps(t_ns, lat, lon, alt, 3, 0.5, 12)

        return run

    def peer() -> Callable[[], None]:
        ekf = FilterpyRoverEkf(config, STEP_NS * 1e-9)

        def run() -> None:
            for k in range(n):
                ekf.predict()
                ekf.update_gyro(gyro[k])
                ekf.update_odometry(speed[k], yaw_rate[k], 0.05, 0.05)
                if (k + 1) % GPS_EVERY == 0:
                    ekf.update_position(gps[k][0], gps[k][1], 0.5)

        return run

    return {
        "ours": n / _best_of(repeats, ours),
        "ours_front_end": n / _best_of(repeats, front_end),
        "filterpy": n / _best_of(repeats, peer),
    }


def time_operations(inputs: Inputs, repeats: int) -> dict[str, dict[str, float]]:
    """Microseconds per predict and per update kind, for ours and filterpy."""
    config = EstimatorConfig()
    n = len(inputs.gyro)
    gyro, speed, yaw_rate = inputs.gyro.tolist(), inputs.speed.tolist(), inputs.yaw_rate.tolist()
    gps = inputs.gps_xy.tolist()
    dt = STEP_NS * 1e-9
    ours_ops: dict[str, Callable[[Any, int], None]] = {
        "predict": lambda f, k: f.predict((k + 1) * STEP_NS),
        "update_gyro": lambda f, k: f.update_gyro(gyro[k]),
        "update_odometry": lambda f, k: f.update_odometry(speed[k], yaw_rate[k], 0.05, 0.05),
        "update_gps": lambda f, k: f.update_position(gps[k][0], gps[k][1], 0.5, gated=False),
    }
    peer_ops: dict[str, Callable[[Any, int], None]] = {
        "predict": lambda f, k: f.predict(),
        "update_gyro": lambda f, k: f.update_gyro(gyro[k]),
        "update_odometry": lambda f, k: f.update_odometry(speed[k], yaw_rate[k], 0.05, 0.05),
        "update_gps": lambda f, k: f.update_position(gps[k][0], gps[k][1], 0.5),
    }
    figures: dict[str, dict[str, float]] = {"ours": {}, "filterpy": {}}
    contenders: dict[str, tuple[dict[str, Callable[[Any, int], None]], Callable[[], Any]]] = {
        "ours": (ours_ops, lambda: _ours(config)),
        "filterpy": (peer_ops, lambda: FilterpyRoverEkf(config, dt)),
    }
    for who, (ops, make) in contenders.items():
        for name in ops:
            figures[who][name] = 1e6 * _per_operation(ops, name, make, n, repeats)
    return figures


def _per_operation(
    ops: dict[str, Callable[[Any, int], None]], name: str, make: Callable[[], Any], n: int, repeats: int
) -> float:
    """Seconds per ``name`` inside realistic cycles (predict then every update), timed call by call.

    Timing each call separately costs two perf_counter reads (~0.1 us), the same for every contender; it
    keeps the filter in its steady state (updates alone, without predicts, drive P towards subnormal
    numbers and measure something no rover does).
    """
    best = math.inf
    for _ in range(repeats):
        ekf = make()
        spent = 0.0
        for k in range(n):
            for op_name, op in ops.items():
                if op_name == name:
                    start = time.perf_counter()
                    op(ekf, k)
                    spent += time.perf_counter() - start
                elif op_name != "update_gps" or (k + 1) % GPS_EVERY == 0:
                    op(ekf, k)
        best = min(best, spent / n)
    return best


def run_benchmark(cycles: int = 20_000, seed: int = 1, repeats: int = 3) -> dict[str, Any]:
    """All figures as one JSON-ready dict."""
    inputs = make_inputs(cycles, seed)
    rates = time_cycles(inputs, repeats)
    return {
        "cycles": cycles,
        "repeats": repeats,
        "cycle": "predict + gyro update + odometry update, GPS update every 10th",
        "cycles_per_s": rates,
        "speedup_vs_filterpy": rates["ours"] / rates["filterpy"],
        "goal_cycles_per_s": GOAL_CYCLES_PER_S,
        "goal_met": rates["ours"] >= GOAL_CYCLES_PER_S,
        "us_per_operation": time_operations(make_inputs(min(cycles, 5_000), seed), repeats),
    }
