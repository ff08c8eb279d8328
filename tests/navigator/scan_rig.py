"""Scans (beams) of known discs for the scan- and rangefinder-perception tests: the simulated lidar's rays
(the simulated rangefinders' readings), through the wire format."""

from __future__ import annotations

from typing import Any

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.distance_sensor import RangeBeam, read_beam
from firmware_bridge.mavlink_transport import memory_pipe_pair
from firmware_bridge.obstacle_scan import ObstacleScan, read_scan, scan_message
from hil.lidar_sim import MIN_RANGE_M, SimLidar
from hil.rangefinder_sim import DEFAULT_YAWS_DEG, SimRangefinders, yaw_ring
from logs.clock import SimClock
from navigator.sensor_mount import AT_CENTRE, SensorMount

Disc = tuple[str, float, float, float, float, float]  # id, x, y, radius, vx, vy


def scan_of(
    discs: list[Disc],
    pose: tuple[float, float, float],
    t_ns: int,
    *,
    noise_m: float = 0.0,
    seed: int = 0,
    mount: SensorMount = AT_CENTRE,
) -> ObstacleScan:
    """What a 360-degree, 72-sector lidar mounted at ``mount`` on a rover at ``pose`` (x, y, yaw) sees of
    ``discs`` at ``t_ns``, as read off an OBSTACLE_DISTANCE message."""
    lidar = SimLidar(
        memory_pipe_pair()[0],
        SimClock(t_ns),
        lambda _t: discs,
        np.random.default_rng(seed),
        noise_m=noise_m,
        mount=mount,
    )
    mav = mavlink2.MAVLink(None, 1, 1)
    msg = scan_message(
        mav,
        t_ns // 1000,
        lidar.ranges(t_ns, *pose),
        increment_deg=lidar.increment_deg,
        angle_offset_deg=lidar.angle_offset_deg,
        min_range_m=MIN_RANGE_M,
        max_range_m=8.0,
    )
    # Through the bytes, as the link would decode them.
    decoded = mavlink2.MAVLink(None).decode(bytearray(msg.pack(mav)))
    return read_scan(decoded, t_ns)


def beams_of(
    discs: list[Disc],
    pose: tuple[float, float, float],
    t_ns: int,
    *,
    fov_deg: float = 15.0,
    yaw_deg: tuple[int, ...] = DEFAULT_YAWS_DEG,
    mount: SensorMount = AT_CENTRE,
) -> list[RangeBeam]:
    """What the simulated ring of rangefinders at ``mount`` on a rover at ``pose`` reads of ``discs`` at
    ``t_ns``, each reading read off its DISTANCE_SENSOR bytes as the link would."""
    sent: list[Any] = []
    ring = SimRangefinders(
        sent.append,
        SimClock(t_ns),
        lambda _t: discs,
        np.random.default_rng(0),
        sensors=yaw_ring(yaw_deg, mount),
        fov_deg=fov_deg,
    )
    ring.step(*pose)
    mav = mavlink2.MAVLink(None, 1, 1)
    beams = [read_beam(mavlink2.MAVLink(None).decode(bytearray(msg.pack(mav))), t_ns) for msg in sent]
    return [beam for beam in beams if beam is not None]
