"""A kinematic rover and its noisy sensors, for estimator tests.

The truth integrates a speed / yaw-rate profile; the sensors are what the estimator would see:
GPS at 5 Hz (0.5 m noise), gyro at 50 Hz (0.005 rad/s noise and a bias), wheel speeds at 50 Hz.
Samples come out in time order as ``(t_ns, kind, values)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from estimator.estimator import Estimator
from estimator.geodesy import Datum, to_geodetic

STEP_NS = 20_000_000  # 50 Hz
GPS_EVERY = 10  # 5 Hz
GPS_STD_M = 0.5
GYRO_STD_RPS = 0.005
WHEEL_STD_MPS = 0.02


@dataclass(frozen=True)
class Truth:
    t_ns: int
    x: float
    y: float
    yaw: float


@dataclass(frozen=True)
class Sample:
    t_ns: int
    kind: str  # "gps", "imu", "wheels"
    values: tuple[float, ...]


def default_profile(t_s: float) -> tuple[float, float]:
    """(speed m/s, yaw rate rad/s): straight, left arc, straight, right circle, slow straight, ..."""
    phase = t_s % 80.0
    if phase < 10.0:
        return 1.0, 0.0
    if phase < 25.0:
        return 0.8, 0.2
    if phase < 35.0:
        return 1.0, 0.0
    if phase < 55.0:
        return 0.6, -0.35
    if phase < 65.0:
        return 0.5, 0.0
    return 0.9, 0.15


def simulate(
    rng: np.random.Generator,
    datum: Datum,
    duration_s: float,
    *,
    start_yaw: float = 2.0,
    gyro_bias_rps: float = 0.01,
    track_m: float = 0.55,
    skid_factor: float = 1.6,
    profile: Callable[[float], tuple[float, float]] = default_profile,
    wheel_slip_rps: Callable[[float], float] = lambda t_s: 0.0,
) -> Iterator[tuple[Truth, list[Sample]]]:
    """Yield the truth and the sensor samples of every 20 ms step.

    ``wheel_slip_rps(t_s)`` is a yaw rate the wheels report but the body does not do (one side spinning).
    """
    x, y, yaw = 3.0, -2.0, start_yaw
    steps = round(duration_s * 1e9 / STEP_NS)
    dt = STEP_NS * 1e-9
    for k in range(1, steps + 1):
        t_ns = k * STEP_NS
        speed, yaw_rate = profile(t_ns * 1e-9)
        heading = yaw + 0.5 * yaw_rate * dt
        x += speed * dt * math.cos(heading)
        y += speed * dt * math.sin(heading)
        yaw += yaw_rate * dt
        samples = [
            Sample(t_ns, "imu", (yaw_rate + gyro_bias_rps + rng.normal(0.0, GYRO_STD_RPS), 0.0, 0.0)),
        ]
        half_diff = 0.5 * (yaw_rate + wheel_slip_rps(t_ns * 1e-9)) * track_m * skid_factor
        left = speed - half_diff + rng.normal(0.0, WHEEL_STD_MPS)
        right = speed + half_diff + rng.normal(0.0, WHEEL_STD_MPS)
        samples.append(Sample(t_ns, "wheels", (left, right)))
        if k % GPS_EVERY == 0:
            e = x + rng.normal(0.0, GPS_STD_M)
            n = y + rng.normal(0.0, GPS_STD_M)
            lat, lon, alt = to_geodetic(datum, e, n, 0.0)
            samples.append(Sample(t_ns, "gps", (lat, lon, alt, 3.0, GPS_STD_M, 12.0)))
        yield Truth(t_ns, x, y, math.atan2(math.sin(yaw), math.cos(yaw))), samples


def feed(estimator: Estimator, samples: list[Sample]) -> None:
    """Hand one step's samples to the estimator the way the onboard loop would."""
    for sample in samples:
        if sample.kind == "gps":
            lat, lon, alt, fix_type, eph, satellites = sample.values
            estimator.on_gps(sample.t_ns, lat, lon, alt, int(fix_type), eph, int(satellites))
        elif sample.kind == "imu":
            estimator.on_imu(sample.t_ns, *sample.values)
        else:
            estimator.on_wheels(sample.t_ns, *sample.values)
