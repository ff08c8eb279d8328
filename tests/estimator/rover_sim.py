"""A kinematic rover and its noisy sensors, for estimator tests.

The truth integrates a speed / yaw-rate profile; the sensors are what the estimator would see:
GPS at 5 Hz (0.5 m noise), gyro at 50 Hz (0.005 rad/s noise and a bias), wheel speeds at 50 Hz.
Samples come out in time order as ``(t_ns, kind, values)``.

Terrain classes change what the wheels report (``GROUND``): the wheel surface runs faster than the ground
by the class's slip (the odometry scale the estimator has to learn) and its speed is noisier on rough
ground. Faults are functions of time: GPS offsets (glitches), GPS outages, the ground share of the wheel
speed (0 = stuck, wheels spinning in place), and a GPS delivery latency.
"""

from __future__ import annotations

import math
from collections import deque
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
class Ground:
    """How a terrain class distorts wheel odometry: wheel speed = slip_scale * ground speed + noise."""

    slip_scale: float
    wheel_std_mps: float


# Longitudinal slip of the wheels of a light rover (a few percent on rock, ~10 % on sand, more in mud).
GROUND = {
    "firm": Ground(1.0, WHEEL_STD_MPS),
    "rocky": Ground(1.03, 0.05),
    "sandy": Ground(1.10, 0.03),
    "muddy": Ground(1.18, 0.04),
}


@dataclass(frozen=True)
class Truth:
    t_ns: int
    x: float
    y: float
    yaw: float
    speed: float = 0.0
    distance: float = 0.0  # path length travelled so far, m


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
    ground: Ground = GROUND["firm"],
    profile: Callable[[float], tuple[float, float]] = default_profile,
    wheel_slip_rps: Callable[[float], float] = lambda t_s: 0.0,
    ground_share: Callable[[float], float] = lambda t_s: 1.0,
    gps_offset_m: Callable[[float], tuple[float, float]] = lambda t_s: (0.0, 0.0),
    gps_available: Callable[[float], bool] = lambda t_s: True,
    gps_latency_steps: int = 0,
) -> Iterator[tuple[Truth, list[Sample]]]:
    """Yield the truth and the sensor samples of every 20 ms step.

    ``wheel_slip_rps(t_s)`` is a yaw rate the wheels report but the body does not do (one side spinning);
    ``ground_share(t_s)`` the share of the wheels' speed the body really makes (0: stuck, spinning).
    A fix taken at step k is delivered ``gps_latency_steps`` steps later, stamped with its delivery time.
    """
    x, y, yaw = 3.0, -2.0, start_yaw
    distance = 0.0
    steps = round(duration_s * 1e9 / STEP_NS)
    dt = STEP_NS * 1e-9
    in_flight: deque[tuple[int, tuple[float, ...]]] = deque()  # (delivery step, values)
    for k in range(1, steps + 1):
        t_ns = k * STEP_NS
        t_s = t_ns * 1e-9
        wheel_speed, yaw_rate = profile(t_s)
        speed = wheel_speed * ground_share(t_s)
        heading = yaw + 0.5 * yaw_rate * dt
        x += speed * dt * math.cos(heading)
        y += speed * dt * math.sin(heading)
        yaw += yaw_rate * dt
        distance += abs(speed) * dt
        samples = [
            Sample(t_ns, "imu", (yaw_rate + gyro_bias_rps + rng.normal(0.0, GYRO_STD_RPS), 0.0, 0.0)),
        ]
        half_diff = 0.5 * (yaw_rate + wheel_slip_rps(t_s)) * track_m * skid_factor
        # The wheels turn at the commanded speed; on loose ground the body makes 1/slip_scale of it.
        surface = speed * ground.slip_scale if ground_share(t_s) > 0.0 else wheel_speed
        left = surface - half_diff + rng.normal(0.0, ground.wheel_std_mps)
        right = surface + half_diff + rng.normal(0.0, ground.wheel_std_mps)
        samples.append(Sample(t_ns, "wheels", (left, right)))
        if k % GPS_EVERY == 0:
            noise = rng.normal(0.0, GPS_STD_M, 2)  # drawn always, so faults do not shift the stream
            if gps_available(t_s):
                dx, dy = gps_offset_m(t_s)
                lat, lon, alt = to_geodetic(datum, x + noise[0] + dx, y + noise[1] + dy, 0.0)
                in_flight.append((k + gps_latency_steps, (lat, lon, alt, 3.0, GPS_STD_M, 12.0)))
        while in_flight and in_flight[0][0] <= k:
            samples.append(Sample(t_ns, "gps", in_flight.popleft()[1]))
        truth = Truth(t_ns, x, y, math.atan2(math.sin(yaw), math.cos(yaw)), speed, distance)
        yield truth, samples


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
