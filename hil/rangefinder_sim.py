"""A simulated ring of single-beam rangefinders, reported by the simulated autopilot as DISTANCE_SENSOR.

On a rover with rangefinders the autopilot reads the sensors (ArduPilot's ``RNGFNDn_*``) and streams one
DISTANCE_SENSOR per sensor and reading, from its own system and component; so does the HIL autopilot for a
scenario with ``[sensors] perception = "rangefinders"`` (``hil.world``). Sensor ``i`` (its message's
``id``) sits and faces where ``sensors[i]`` says (a ``navigator.sensor_mount.SensorMount``: forward and
left of the rover's reference point, its direction counter-clockwise from the rover's front). It reports
that direction as MAVLink names it: MAV_SENSOR_ROTATION_YAW_<n> for a multiple of 45 degrees (clockwise),
otherwise MAV_SENSOR_ROTATION_CUSTOM with the yaw's quaternion, as a PX4 sensor mounted at any angle does
(``yaw_ring`` builds the older ring of 45-degree steps from one mount point). At ``rate_hz`` each reports
the nearest obstacle edge within its cone: a fan of rays at most a degree apart, one of them along the axis
(that one alone for a zero-width beam), cast from the sensor against the true obstacles with the lidar's
geometry (``hil.ray_cast``), the nearest hit of the fan, plus Gaussian noise of ``noise_m`` from its own
generator (one draw per sensor and reading, hit or not), out to ``range_m``. The cone's width goes out as
``horizontal_fov``; a reading nearer than ``MIN_RANGE_M`` as it is (a too-close one), nothing within
range as ``max_distance + 1``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.distance_sensor import ORIENTATION_OF_YAW_DEG, beam_message
from firmware_bridge.sensor_orientation import CUSTOM
from hil.ray_cast import ObstacleTruth, nearest_hits
from logs.clock import Clock, to_ns
from navigator.sensor_mount import AT_CENTRE, SensorMount

MIN_RANGE_M = 0.2  # a sonar's or small 1-D lidar's nearest measurable distance
RAY_SPACING_DEG = 1.0
DEFAULT_YAWS_DEG = (0, 45, 315, 90, 270)  # front, front-right, front-left, right, left


class SimRangefinders:
    """Measures the true obstacles from the rover's pose at ``rate_hz`` and hands each reading, as a
    DISTANCE_SENSOR, to ``send`` (the simulated autopilot's ``send_sensor``)."""

    def __init__(
        self,
        send: Callable[[Any], None],
        clock: Clock,
        obstacles: ObstacleTruth,
        rng: np.random.Generator,
        *,
        sensors: Sequence[SensorMount] | None = None,
        fov_deg: float = 15.0,
        range_m: float = 8.0,
        rate_hz: float = 10.0,
        noise_m: float = 0.0,
    ) -> None:
        sensors = yaw_ring(DEFAULT_YAWS_DEG) if sensors is None else tuple(sensors)
        if not sensors:
            raise ValueError("a ring of rangefinders needs at least one sensor")
        if not (math.isfinite(fov_deg) and 0.0 <= fov_deg <= 90.0):
            raise ValueError(f"rangefinder fov_deg must be in [0, 90], got {fov_deg}")
        if not (math.isfinite(range_m) and range_m > MIN_RANGE_M):
            raise ValueError(f"rangefinder range_m must be > {MIN_RANGE_M}, got {range_m}")
        if not (math.isfinite(rate_hz) and rate_hz > 0.0):
            raise ValueError(f"rangefinder rate_hz must be > 0, got {rate_hz}")
        if not (math.isfinite(noise_m) and noise_m >= 0.0):
            raise ValueError(f"rangefinder noise_m must be >= 0, got {noise_m}")
        self._send = send
        self._clock = clock
        self._obstacles = obstacles
        self._rng = rng
        self._sensors = sensors
        self._orientations = [mavlink_orientation(sensor.yaw_rad) for sensor in sensors]
        self._fov_rad = math.radians(fov_deg)
        self._range_m = range_m
        self._noise_m = noise_m
        self._period_ns = to_ns(1.0 / rate_hz)
        # An odd number, so that one ray runs along the axis: a zero-width beam is that ray alone.
        rays = 2 * math.ceil(fov_deg / RAY_SPACING_DEG / 2.0) + 1
        self._rays = rays
        fan = np.linspace(-self._fov_rad / 2.0, self._fov_rad / 2.0, rays)
        # Every ray of every sensor, counter-clockwise from the rover's front, sensor by sensor.
        self._ray_angles = np.concatenate([sensor.yaw_rad + fan for sensor in sensors])
        # Sensors that share a place are cast together (the older ring: all of them, one call).
        self._places: dict[tuple[float, float], list[int]] = {}
        for index, sensor in enumerate(sensors):
            self._places.setdefault((sensor.forward_m, sensor.left_m), []).append(index)
        # For building the messages only: the autopilot packs them with its own ids and sequence.
        self._mav = mavlink2.MAVLink(None, 0, 0)
        self.next_ns = clock.now_ns()
        self.sent = 0

    @property
    def sensor_count(self) -> int:
        return len(self._orientations)

    def ranges(self, t_ns: int, x: float, y: float, yaw: float) -> list[float | None]:
        """Each sensor's reading (m from the sensor; None: nothing within range), noise included, the
        rover's reference point at pose (x, y, yaw) at ``t_ns``."""
        noise = self._rng.normal(0.0, 1.0, len(self._sensors)) * self._noise_m
        headings = (self._ray_angles + yaw).reshape(len(self._sensors), self._rays)
        nearest = np.empty(len(self._sensors))
        discs = self._obstacles(t_ns)
        for (forward_m, left_m), indices in self._places.items():
            sx, sy = SensorMount(forward_m, left_m).origin(x, y, yaw)
            rays = headings[indices].ravel()
            hits = nearest_hits(sx, sy, np.cos(rays), np.sin(rays), discs, self._range_m)
            nearest[indices] = hits.reshape(len(indices), self._rays).min(axis=1)
        measured = np.maximum(nearest + noise, 0.0)
        return [
            float(r) if math.isfinite(n) and r <= self._range_m else None
            for r, n in zip(measured.tolist(), nearest.tolist(), strict=True)
        ]

    def step(self, x: float, y: float, yaw: float) -> None:
        """Measure and send if a reading is due at the clock's now (the rover at x, y ENU m, facing yaw rad
        from east)."""
        now = self._clock.now_ns()
        if now < self.next_ns:
            return
        following = self.next_ns + self._period_ns
        self.next_ns = following if following > now else now + self._period_ns
        time_boot_ms = now // 1_000_000
        for sensor_id, ((orientation, quaternion), reading) in enumerate(
            zip(self._orientations, self.ranges(now, x, y, yaw), strict=True)
        ):
            self._send(
                beam_message(
                    self._mav,
                    time_boot_ms,
                    reading,
                    sensor_id=sensor_id,
                    orientation=orientation,
                    quaternion=quaternion,
                    min_range_m=MIN_RANGE_M,
                    max_range_m=self._range_m,
                    fov_rad=self._fov_rad,
                )
            )
            self.sent += 1


def yaw_ring(yaw_deg: Sequence[int], mount: SensorMount = AT_CENTRE) -> tuple[SensorMount, ...]:
    """Sensors at ``mount``'s place, each facing ``yaw_deg[i]`` degrees clockwise from the rover's front
    (multiples of 45, each once): the ring a scenario's ``rangefinder_yaw_deg`` describes."""
    if not yaw_deg or any(yaw not in ORIENTATION_OF_YAW_DEG for yaw in yaw_deg):
        raise ValueError(f"rangefinder yaw_deg must be multiples of 45 in [0, 315], got {list(yaw_deg)}")
    if len(set(yaw_deg)) != len(yaw_deg):
        raise ValueError(f"rangefinder yaw_deg lists a direction twice: {list(yaw_deg)}")
    return tuple(SensorMount(mount.forward_m, mount.left_m, -math.radians(yaw)) for yaw in yaw_deg)


_NO_QUATERNION = (0.0, 0.0, 0.0, 0.0)


def mavlink_orientation(yaw_rad: float) -> tuple[int, tuple[float, float, float, float]]:
    """How a level sensor facing ``yaw_rad`` (counter-clockwise from the rover's front) says so:
    (MAV_SENSOR_ROTATION_YAW_<n>, no quaternion) on a 45-degree step, else (CUSTOM, the rotation about
    the body's down axis by the clockwise angle, w x y z)."""
    clockwise_deg = -math.degrees(yaw_rad) % 360.0
    step = round(clockwise_deg / 45.0)
    if abs(clockwise_deg - 45.0 * step) < 1e-9:
        return ORIENTATION_OF_YAW_DEG[45 * (step % 8)], _NO_QUATERNION
    half = math.radians(clockwise_deg) / 2.0
    return CUSTOM, (math.cos(half), 0.0, 0.0, math.sin(half))
