"""MAVLink OBSTACLE_DISTANCE (id 330): a range scan around the rover, read and written.

The message carries 72 ranges in centimetres, ``increment`` degrees apart (``increment_f`` when non-zero),
the first at ``angle_offset`` degrees, angles clockwise. ``frame`` says from what: MAV_FRAME_BODY_FRD from
the vehicle's front (a body-mounted lidar), MAV_FRAME_GLOBAL or MAV_FRAME_LOCAL_NED from north. A range of
``max_distance + 1`` means nothing there; UINT16_MAX means that sector is not measured; 0 means an obstacle
practically touching the sensor. A lidar driver on the companion computer or the autopilot sends it (PX4
streams it, ArduPilot reads it); the HIL peer's simulated lidar (``hil.lidar_sim``) does too.

The ranges count from the sensor, wherever it sits, and a body-frame scan's angles from the sensor's own
forward direction (what a driver that knows nothing of the mount reports): the rover config's
``[perception]`` mount moves and turns them onto the rover (``navigator.sensor_mount``, applied where
returns become map points, in ``navigator.scan_clusters``).

``read_scan`` turns one message into an ``ObstacleScan`` in our conventions (angles counter-clockwise, in
radians, from the sensor's forward axis or from east), or refuses it with ``ScanRejected`` naming what was
wrong; the link counts and logs each refusal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import common as mavlink2

SECTORS = 72
UNMEASURED_CM = 65535
_BODY_FRAMES = frozenset({mavlink2.MAV_FRAME_BODY_FRD})
_NORTH_FRAMES = frozenset({mavlink2.MAV_FRAME_GLOBAL, mavlink2.MAV_FRAME_LOCAL_NED})


class ScanRejected(ValueError):
    """An OBSTACLE_DISTANCE that cannot be read as a scan; the message says why."""


@dataclass(frozen=True)
class ObstacleScan:
    """One OBSTACLE_DISTANCE: the sectors that saw something, in ray order.

    ``body_frame``: angles count counter-clockwise from the sensor's forward axis (else from east, ENU);
    ranges count from the sensor either way.
    ``rays``: ``(angle_rad, range_m)`` for every measured sector, with ``range_m`` None where the sector saw
    nothing within ``max_range_m``; unmeasured sectors are left out, so two neighbours in ``rays`` are
    neighbours on the sensor only if their angles are one ``increment_rad`` apart.
    ``full_circle``: the 72 sectors cover 360 degrees, so the last ray neighbours the first.
    """

    t_ns: int
    body_frame: bool
    increment_rad: float
    rays: tuple[tuple[float, float | None], ...]
    min_range_m: float
    max_range_m: float
    full_circle: bool


def read_scan(msg: Any, t_ns: int) -> ObstacleScan:
    """``msg`` (a decoded OBSTACLE_DISTANCE) as a scan received at ``t_ns``; ``ScanRejected`` if it is not
    one."""
    if msg.frame in _BODY_FRAMES:
        body = True
    elif msg.frame in _NORTH_FRAMES:
        body = False
    else:
        raise ScanRejected(f"frame {msg.frame} is neither MAV_FRAME_BODY_FRD nor north-aligned")
    increment_deg = float(msg.increment_f) if msg.increment_f else float(msg.increment)
    if not (math.isfinite(increment_deg) and increment_deg > 0.0):
        raise ScanRejected(f"increment {increment_deg} deg is not a positive angle")
    if increment_deg * SECTORS > 360.0 + 1e-3:
        raise ScanRejected(f"increment {increment_deg} deg makes 72 sectors overlap (more than 360 deg)")
    offset_deg = float(msg.angle_offset)
    if not math.isfinite(offset_deg):
        raise ScanRejected(f"angle_offset {offset_deg} is not a number")
    if msg.max_distance <= msg.min_distance:
        raise ScanRejected(
            f"max_distance {msg.max_distance} cm is not above min_distance {msg.min_distance} cm"
        )
    distances = msg.distances
    if len(distances) != SECTORS:
        raise ScanRejected(f"{len(distances)} distances, not {SECTORS}")
    rays: list[tuple[float, float | None]] = []
    nothing_from_cm = msg.max_distance + 1
    nearest_m = msg.min_distance / 100.0
    for index, cm in enumerate(distances):
        if cm == UNMEASURED_CM:
            continue
        clockwise_deg = offset_deg + index * increment_deg
        angle = -math.radians(clockwise_deg) if body else math.radians(90.0 - clockwise_deg)
        if cm >= nothing_from_cm:
            rays.append((angle, None))
        else:
            # 0 (the spec: "practically touching the sensor") and anything nearer than the sensor can tell
            # are an obstacle at its nearest range, not nothing: the nearest obstacle must not vanish.
            rays.append((angle, max(cm / 100.0, nearest_m)))
    return ObstacleScan(
        t_ns,
        body,
        math.radians(increment_deg),
        tuple(rays),
        msg.min_distance / 100.0,
        msg.max_distance / 100.0,
        increment_deg * SECTORS >= 360.0 - 1e-3,
    )


def scan_message(
    mav: mavlink2.MAVLink,
    time_usec: int,
    ranges_m: list[float | None],
    *,
    increment_deg: float,
    angle_offset_deg: float,
    min_range_m: float,
    max_range_m: float,
) -> Any:
    """An OBSTACLE_DISTANCE in the body frame from 72 ranges (None: nothing within ``max_range_m``),
    the first at ``angle_offset_deg`` clockwise from the sensor's forward direction, each ``increment_deg``
    further clockwise."""
    if len(ranges_m) != SECTORS:
        raise ValueError(f"an OBSTACLE_DISTANCE holds {SECTORS} ranges, got {len(ranges_m)}")
    max_cm = round(max_range_m * 100.0)
    min_cm = round(min_range_m * 100.0)
    distances = [max_cm + 1 if r is None else min(max(round(r * 100.0), min_cm), max_cm) for r in ranges_m]
    return mav.obstacle_distance_encode(
        time_usec,
        mavlink2.MAV_DISTANCE_SENSOR_LASER,
        distances,
        0,  # increment in whole degrees: 0, increment_f says it
        min_cm,
        max_cm,
        increment_deg,
        angle_offset_deg,
        mavlink2.MAV_FRAME_BODY_FRD,
    )
