"""A simulated 2D lidar on the rover, sending its scans over MAVLink as OBSTACLE_DISTANCE.

The rover in another process (``rover run``) has no other way to perceive what is not in its map: the
hidden obstacles and the moving ones. This is how a real one would: a lidar driver, a MAVLink component of
the rover's system (MAV_COMP_ID_OBSTACLE_AVOIDANCE), sends each scan; the onboard stack tracks obstacles
from them (``navigator.scan_tracker``). 72 rays, one per OBSTACLE_DISTANCE sector, spread over
``fov_deg`` centred on the sensor's forward direction, are cast from where the sensor sits on the rover
(``mount``, ``navigator.sensor_mount``: the rover's centre and its front by default) against the true
obstacles (discs; ``hil.ray_cast``) at ``rate_hz``; each ray reports the nearest edge it meets within
``range_m``, plus Gaussian noise of ``noise_m`` from its own generator (72 draws per scan, hit or not:
the noise does not depend on the path). Like a driver that knows nothing of the mount, it counts the
angles from the sensor's forward direction: the rover must be told where its lidar sits (``[perception]``
``mount_*``).
"""

from __future__ import annotations

import logging
import math

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.errors import BridgeOperationError
from firmware_bridge.mavlink_frames import send_unsigned_v2
from firmware_bridge.mavlink_transport import Transport
from firmware_bridge.obstacle_scan import SECTORS, scan_message
from hil.ray_cast import ObstacleTruth, nearest_hits
from logs.clock import Clock, to_ns
from navigator.sensor_mount import AT_CENTRE, SensorMount

logger = logging.getLogger(__name__)

MIN_RANGE_M = 0.05


class SimLidar:
    """Scans the true obstacles from the rover's pose at ``rate_hz`` and sends each as OBSTACLE_DISTANCE."""

    def __init__(
        self,
        transport: Transport,
        clock: Clock,
        obstacles: ObstacleTruth,
        rng: np.random.Generator,
        *,
        range_m: float = 8.0,
        rate_hz: float = 10.0,
        noise_m: float = 0.0,
        fov_deg: float = 360.0,
        mount: SensorMount = AT_CENTRE,
        system_id: int = 1,
        component_id: int = mavlink2.MAV_COMP_ID_OBSTACLE_AVOIDANCE,
    ) -> None:
        if not (math.isfinite(range_m) and range_m > MIN_RANGE_M):
            raise ValueError(f"lidar range_m must be > {MIN_RANGE_M}, got {range_m}")
        if not (math.isfinite(rate_hz) and rate_hz > 0.0):
            raise ValueError(f"lidar rate_hz must be > 0, got {rate_hz}")
        if not (math.isfinite(fov_deg) and 0.0 < fov_deg <= 360.0):
            raise ValueError(f"lidar fov_deg must be in (0, 360], got {fov_deg}")
        if not (math.isfinite(noise_m) and noise_m >= 0.0):
            raise ValueError(f"lidar noise_m must be >= 0, got {noise_m}")
        if not all(map(math.isfinite, (mount.forward_m, mount.left_m, mount.yaw_rad))):
            raise ValueError(f"lidar mount must be finite, got {mount}")
        self._clock = clock
        self._obstacles = obstacles
        self._rng = rng
        self._range_m = range_m
        self._noise_m = noise_m
        self._mount = mount
        self._period_ns = to_ns(1.0 / rate_hz)
        self.increment_deg = fov_deg / SECTORS
        # Sector i's ray, clockwise from the sensor's front: a full circle starts straight ahead, a
        # narrower view is centred on it.
        self.angle_offset_deg = 0.0 if fov_deg >= 360.0 else -fov_deg / 2.0 + self.increment_deg / 2.0
        clockwise = np.radians(self.angle_offset_deg + self.increment_deg * np.arange(SECTORS))
        self._sensor_angles = -clockwise  # counter-clockwise from the sensor's front, as our yaw counts
        # pymavlink writes each packed frame to its "file": the transport takes them as they are.
        self._mav = mavlink2.MAVLink(transport, system_id, component_id)
        self.next_ns = clock.now_ns()
        self.sent = 0
        self.send_errors = 0

    def ranges(self, t_ns: int, x: float, y: float, yaw: float) -> list[float | None]:
        """Each ray's range from the sensor to the nearest obstacle edge, the rover's reference point at
        pose (x, y, yaw), at ``t_ns`` (None: nothing within range), noise included."""
        noise = self._rng.normal(0.0, 1.0, SECTORS) * self._noise_m
        sx, sy = self._mount.origin(x, y, yaw)
        headings = self._sensor_angles + self._mount.facing(yaw)
        nearest = nearest_hits(
            sx, sy, np.cos(headings), np.sin(headings), self._obstacles(t_ns), self._range_m
        )
        measured = np.maximum(nearest + noise, MIN_RANGE_M)
        return [
            float(r) if math.isfinite(n) and r <= self._range_m else None
            for r, n in zip(measured.tolist(), nearest.tolist(), strict=True)
        ]

    def step(self, x: float, y: float, yaw: float) -> None:
        """Scan and send if one is due at the clock's now (the rover at x, y ENU m, facing yaw rad from
        east)."""
        now = self._clock.now_ns()
        if now < self.next_ns:
            return
        following = self.next_ns + self._period_ns
        self.next_ns = following if following > now else now + self._period_ns
        msg = scan_message(
            self._mav,
            now // 1000,
            self.ranges(now, x, y, yaw),
            increment_deg=self.increment_deg,
            angle_offset_deg=self.angle_offset_deg,
            min_range_m=MIN_RANGE_M,
            max_range_m=self._range_m,
        )
        try:
            send_unsigned_v2(self._mav, msg)
        except (BridgeOperationError, OSError) as err:
            self.send_errors += 1
            logger.debug("simulated lidar: cannot send a scan: %s", err)
            return
        self.sent += 1
