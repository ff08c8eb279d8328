"""Sensor models of the simulated autopilot: what GPS and IMU report of the true state, faults included.

GPS: white position noise (σ per horizontal axis, 2σ vertical), a fixed latency (the receiver reports where
the rover was ``latency_s`` ago, as real receivers do by 0.1-0.2 s), a fix type and satellite count, random
dropouts. IMU: white noise plus a constant bias per axis; gravity on slopes comes in through the specific
force the dynamics computes. Faults (``hil.faults``) change each of these while active.

Random numbers are drawn in a fixed pattern per sample whatever the faults do, so a fault never shifts
the noise of later samples (a trial with a fault differs from one without only where the fault acts).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from hil.faults import Fault, FaultSchedule
from logs.clock import to_ns

FIX_NONE = 0
FIX_3D = 3
# Per-axis scale of the GPS noise: east, north, and up twice as large (receivers are worse vertically).
_GPS_NOISE_AXES = (1.0, 1.0, 2.0)


class GpsSample(NamedTuple):
    """The truth a GPS fix is computed from (ENU metres, yaw CCW from east). A NamedTuple: one is kept
    every physics tick, and a frozen dataclass cost several times as much to build."""

    t_ns: int
    x_m: float
    y_m: float
    z_m: float
    yaw_rad: float
    speed_mps: float
    lateral_speed_mps: float = 0.0  # sideways (y left): a sliding body's ground track is off its heading
    roll_rad: float = 0.0  # the body's tilt: its speeds are in its own plane, the GPS's over the ground
    pitch_rad: float = 0.0


@dataclass(frozen=True)
class GpsFix:
    x_m: float
    y_m: float
    z_m: float
    yaw_rad: float
    speed_mps: float
    fix_type: int
    satellites: int
    eph_m: float
    lateral_speed_mps: float = 0.0
    roll_rad: float = 0.0
    pitch_rad: float = 0.0


class GpsModel:
    """Turns the truth history into fixes: latency, noise, dropouts, fix quality and GPS faults."""

    def __init__(
        self,
        rng: np.random.Generator,
        faults: FaultSchedule,
        *,
        noise_m: float,
        latency_s: float = 0.0,
        dropout_probability: float = 0.0,
        satellites: int = 12,
    ) -> None:
        self._rng = rng
        self._faults = faults
        self._noise_m = noise_m
        self._latency_ns = to_ns(latency_s)
        self._dropout = dropout_probability
        self._satellites = satellites
        self._history: deque[GpsSample] = deque()
        # Keep just enough truth for the longest look-back the latency and delay faults can ask for.
        longest_delay_s = max((f.delay_s for f in faults.faults if f.target == "gps"), default=0.0)
        self._horizon_ns = self._latency_ns + to_ns(longest_delay_s) + to_ns(0.1)
        # Without a latency or a delay fault a fix reports the truth of its own instant: nothing older is
        # ever looked up, and the autopilot need record only the truth of the ticks a fix is due.
        self.looks_back = self._latency_ns > 0 or longest_delay_s > 0
        # Whether any GPS fault is scheduled at all: without one, a fix asks the schedule nothing.
        self._has_faults = faults.scheduled("gps")
        self._fixes_due = 0
        self.dropped = 0

    def record(self, sample: GpsSample) -> None:
        """Remember the truth (every physics tick) so a delayed fix can look back."""
        self._history.append(sample)
        horizon = sample.t_ns - self._horizon_ns
        while len(self._history) > 1 and self._history[0].t_ns < horizon:
            self._history.popleft()

    def fix(self, now: int) -> GpsFix | None:
        """The fix due at ``now``, or None when it is lost (dropout, loss fault, slow fault)."""
        # Three standard normals, scaled per axis and by the noise in plain floats: the same IEEE products
        # in the same order as on the arrays they were once (normal(0, 1) * axes * noise_m), the same numbers.
        n0, n1, n2 = self._rng.normal(0.0, 1.0, 3).tolist()
        drop_draw = float(self._rng.random())
        self._fixes_due += 1
        kinds = {f.kind: f for f in self._faults.active_all("gps", now)} if self._has_faults else {}
        if "off" in kinds:
            self.dropped += 1
            return None
        slow = kinds.get("slow")
        if slow is not None and (self._fixes_due % max(1, round(slow.factor))) != 0:
            self.dropped += 1
            return None
        intermittent = kinds.get("intermittent")
        if drop_draw < self._dropout or (intermittent is not None and drop_draw < intermittent.probability):
            self.dropped += 1
            return None
        delay_ns = self._latency_ns
        delayed = kinds.get("delayed")
        if delayed is not None:
            delay_ns += to_ns(delayed.delay_s)
        truth = self._at(now - delay_ns)
        noise_m = self._noise_m
        east, north, up = _GPS_NOISE_AXES
        x = truth.x_m + n0 * east * noise_m
        y = truth.y_m + n1 * north * noise_m
        z = truth.z_m + n2 * up * noise_m
        wrong = kinds.get("wrong")
        if wrong is not None:
            x += wrong.offset_m[0]
            y += wrong.offset_m[1]
        if "garbage" in kinds:
            # A receiver reporting nonsense: no fix, no satellites, a position far off.
            return GpsFix(x + 1e4, y - 1e4, z, truth.yaw_rad, 0.0, FIX_NONE, 0, 9999.0)
        return GpsFix(
            x,
            y,
            z,
            truth.yaw_rad,
            truth.speed_mps,
            FIX_3D,
            self._satellites,
            self._noise_m,
            truth.lateral_speed_mps,
            truth.roll_rad,
            truth.pitch_rad,
        )

    def _at(self, t_ns: int) -> GpsSample:
        """The newest recorded truth at or before ``t_ns`` (the oldest one if none is that old)."""
        chosen = self._history[0]
        for sample in reversed(self._history):
            if sample.t_ns <= t_ns:
                return sample
        return chosen


class ImuReading(NamedTuple):
    gyro_flu_rps: tuple[float, float, float]
    accel_flu_mps2: tuple[float, float, float]


class ImuModel:
    """Gyro and accelerometer in body FLU axes: truth + bias + white noise, with IMU faults."""

    def __init__(
        self,
        rng: np.random.Generator,
        faults: FaultSchedule,
        *,
        gyro_noise_rps: float,
        accel_noise_mps2: float,
        gyro_bias_rps: tuple[float, float, float] = (0.0, 0.0, 0.0),
        accel_bias_mps2: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:
        for name, sigma in (("gyro_noise_rps", gyro_noise_rps), ("accel_noise_mps2", accel_noise_mps2)):
            # Checked here: the draws (standard normals, scaled in read) would not refuse a negative one.
            if not (math.isfinite(sigma) and sigma >= 0.0):
                raise ValueError(f"ImuModel {name} must be a finite number >= 0, got {sigma}")
        self._rng = rng
        self._faults = faults
        self._gyro_noise = gyro_noise_rps
        self._accel_noise = accel_noise_mps2
        self._gyro_bias = tuple(float(b) for b in gyro_bias_rps)
        self._accel_bias = tuple(float(b) for b in accel_bias_mps2)
        self._last: ImuReading | None = None
        # Whether any IMU fault is scheduled at all: without one, a reading asks the schedule nothing.
        self._has_faults = faults.scheduled("imu")

    def read(
        self, now: int, yaw_rate_rps: float, specific_force_flu: tuple[float, float, float]
    ) -> ImuReading | None:
        """The reading at ``now``; None while an ``imu/off`` fault is active."""
        # Six standard normal draws in one call, three for the gyro then three for the accelerometer, each
        # scaled as numpy's normal(0, sigma) scales its draw (0 + sigma z): the numbers two calls of
        # normal(0.0, sigma, 3) gave, for one call's overhead.
        z0, z1, z2, z3, z4, z5 = self._rng.standard_normal(6).tolist()
        gyro_sigma, accel_sigma = self._gyro_noise, self._accel_noise
        wrong: Fault | None = None
        if self._has_faults:  # without an IMU fault scheduled (the usual trial) no fault is looked up
            kinds = {f.kind: f for f in self._faults.active_all("imu", now)}
            if "off" in kinds:
                return None
            if "stuck" in kinds and self._last is not None:
                return self._last
            wrong = kinds.get("wrong")
        # Three-element sums in plain floats (once per 20 ms; numpy's per-call overhead was most of the
        # model's time). The same IEEE additions in the same order as the arrays did: the same numbers.
        gb, ab = self._gyro_bias, self._accel_bias
        f0, f1, f2 = specific_force_flu
        gyro = (
            0.0 + gb[0] + (0.0 + gyro_sigma * z0),
            0.0 + gb[1] + (0.0 + gyro_sigma * z1),
            float(yaw_rate_rps) + gb[2] + (0.0 + gyro_sigma * z2),
        )
        accel = (
            float(f0) + ab[0] + (0.0 + accel_sigma * z3),
            float(f1) + ab[1] + (0.0 + accel_sigma * z4),
            float(f2) + ab[2] + (0.0 + accel_sigma * z5),
        )
        if wrong is not None:
            gyro = _plus(gyro, wrong.gyro_bias_rps)
            accel = _plus(accel, wrong.accel_bias_mps2)
        reading = ImuReading(gyro, accel)
        self._last = reading
        return reading


def _plus(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    """``a + b`` for three-vectors, in plain floats."""
    return (a[0] + float(b[0]), a[1] + float(b[1]), a[2] + float(b[2]))


def ground_velocity_enu(
    yaw_rad: float, speed_mps: float, lateral_speed_mps: float, roll_rad: float, pitch_rad: float
) -> tuple[float, float]:
    """The body's velocity over the ground (east, north; m/s) from its speeds in its own plane: forward
    ``speed_mps`` along the heading tilted by the pitch, sideways ``lateral_speed_mps`` along the body's y
    axis, ``(-sin(roll) sin(pitch), cos(roll))`` in the heading's frame. The simulator moves the body by the
    same law (``hil.dynamics_kernel``), so this is the rate its position changes at."""
    forward = speed_mps * math.cos(pitch_rad)
    cos_yaw, sin_yaw = math.cos(yaw_rad), math.sin(yaw_rad)
    east, north = forward * cos_yaw, forward * sin_yaw
    if lateral_speed_mps != 0.0:
        across = -math.sin(roll_rad) * math.sin(pitch_rad)
        along_left = math.cos(roll_rad)
        east += lateral_speed_mps * (across * cos_yaw - along_left * sin_yaw)
        north += lateral_speed_mps * (across * sin_yaw + along_left * cos_yaw)
    return east, north


def ground_speed_mps(speed_mps: float, lateral_speed_mps: float, roll_rad: float, pitch_rad: float) -> float:
    """The GPS's speed over ground: the horizontal speed of ``ground_velocity_enu`` (while the body does not
    slide, ``abs(speed) cos(pitch)``: on level ground the very float it always was)."""
    if lateral_speed_mps == 0.0:
        return abs(speed_mps) * math.cos(pitch_rad)
    return math.hypot(*ground_velocity_enu(0.0, speed_mps, lateral_speed_mps, roll_rad, pitch_rad))


def course_over_ground_deg(
    yaw_rad: float, speed_mps: float, lateral_speed_mps: float, roll_rad: float, pitch_rad: float
) -> float:
    """The GPS's course over ground as a compass bearing: where the body moves over the ground, which a
    sideways slide turns off its heading (a rover sliding downhill while it drives along the contour tracks
    downhill of it). Without a slide, ``course_bearing_deg`` of the heading, the same float as before slides
    existed; standing still, the heading too."""
    if lateral_speed_mps == 0.0:
        return course_bearing_deg(yaw_rad, speed_mps)
    east, north = ground_velocity_enu(yaw_rad, speed_mps, lateral_speed_mps, roll_rad, pitch_rad)
    return math.degrees(math.atan2(east, north)) % 360.0


def course_bearing_deg(yaw_rad: float, speed_mps: float) -> float:
    """Course over ground as a compass bearing (degrees clockwise from north) for an ENU yaw."""
    heading = yaw_rad if speed_mps >= 0 else yaw_rad + math.pi
    return math.degrees(math.pi / 2.0 - heading) % 360.0
