"""MAVLink DISTANCE_SENSOR (id 132): one rangefinder's reading, read and written.

A single-beam rangefinder (a sonar, a 1-D lidar such as LightWare or Benewake) reports one distance along
the direction it faces. ArduPilot and PX4 stream one DISTANCE_SENSOR per sensor and reading; the HIL
autopilot's simulated ring does too (``hil.rangefinder_sim``). The fields, as pymavlink's common dialect
defines them: ``min_distance``, ``max_distance``, ``current_distance`` in centimetres (uint16);
``orientation`` a MAV_SENSOR_ORIENTATION (``quaternion`` with MAV_SENSOR_ROTATION_CUSTOM); ``id`` the
sensor's onboard id; ``horizontal_fov`` in radians, 0 when unknown; ``signal_quality`` a percentage, 0
unknown, 1 invalid, 100 best; ``vertical_fov`` in place of ``horizontal_fov`` for a sensor on its side
(rolled near 90 degrees: its own vertical spans the rover's horizontal plane). ``type`` and
``covariance`` are not read.

Orientation. Where the sensor looks comes from ``firmware_bridge.sensor_orientation``: every named
MAV_SENSOR_ORIENTATION (roll, then pitch, then yaw, in FRD, as ArduPilot applies them) and
MAV_SENSOR_ROTATION_CUSTOM with the message's quaternion. MAV_SENSOR_ROTATION_YAW_<n> turns the sensor's
forward axis ``n`` degrees clockwise seen from above, as ArduPilot's ``RNGFND_ORIENT`` (2 = right, 6 =
left) and PX4's DistanceSensor (``ROTATION_RIGHT_FACING = 2``, ``ROTATION_LEFT_FACING = 6``) use it. (The
dialect's text on the field says "left-facing: ROTATION_YAW_90" and "backward-facing:
ROTATION_PITCH_180"; the first contradicts the rotation and both autopilots, and is not followed.) A roll
does not move the forward axis: a sensor upside down (ROLL_180_YAW_<n>) or on its side (ROLL_90_YAW_<n>)
looks where YAW_<n> does. A sensor tilted more than ``MAX_TILT_RAD`` (10 degrees) up or down, PITCH_90
and PITCH_270 (up and down) among them, is a ground, ceiling or cliff sensor, not an obstacle sensor for
a rover: not refused but returned as None (the link counts it as not used). One tilted less gives its
horizontal distances. An orientation that is no MAV_SENSOR_ORIENTATION, and CUSTOM without a rotation in
its quaternion (all zeros: the field's "invalid"), is refused.

Distances. A reading above ``max_distance`` is nothing within range (ArduPilot's OutOfRangeHigh); one
between ``min_distance`` and ``max_distance`` an obstacle there. One below ``min_distance`` but at least
1 cm is too close to measure: an obstacle at ``min_distance``, as OBSTACLE_DISTANCE's nearest returns are
(the nearest obstacle must not vanish). 0 below a non-zero ``min_distance`` is no reading at all (PX4's
drivers send 0 with an invalid quality, hobby drivers 0 with quality 0 for "nothing measured"; an
obstacle too near a sensor gives the sensor's own small reading, not 0) and is refused, as are non-finite
or negative distances, ``max_distance`` not above ``min_distance``, ``signal_quality`` 1 (invalid) or past
100, and a ``horizontal_fov`` that is not a finite angle in [0, 2 pi]. ``read_beam`` raises
``BeamRejected`` naming the field; the link counts and logs each refusal.

The reading counts from the sensor, wherever it sits on the rover: the rover config's ``[perception]
rangefinders`` table places each sensor id (``navigator.beam_detections``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.sensor_orientation import OrientationError, facing

INVALID_SIGNAL = 1
# A beam tilted further than this from the horizontal is not an obstacle sensor for a rover: one 10
# degrees down from 0.3 m meets flat ground 1.7 m out, within a sonar's range, and reports it as an
# obstacle; one as far up is 0.6 m above the ground 1.7 m out and passes over a 0.5 m rock there. Closer to
# level, the reading is placed in the horizontal plane at its horizontal distance (range x cos tilt).
MAX_TILT_RAD = math.radians(10.0)
# The orientation a simulated sensor turned ``45 k`` degrees clockwise reports (hil.rangefinder_sim).
ORIENTATION_OF_YAW_DEG = {45 * steps: mavlink2.MAV_SENSOR_ROTATION_NONE + steps for steps in range(8)}


class BeamRejected(ValueError):
    """A DISTANCE_SENSOR that cannot be read as a reading; the message says why."""


@dataclass(frozen=True)
class RangeBeam:
    """One rangefinder reading, received at ``t_ns``.

    ``sensor_id``: the message's ``id`` (the rover config places each id on the rover).
    ``bearing_rad``: the direction the sensor faces, counter-clockwise from the rover's front, in (-pi, pi].
    ``range_m``: the distance from the sensor to the nearest obstacle in its field of view; None where it
    saw nothing within ``max_range_m``; ``min_range_m`` for one too close to measure.
    ``fov_rad``: the horizontal field of view the message gave; None when it said 0 (unknown).
    """

    t_ns: int
    sensor_id: int
    bearing_rad: float
    range_m: float | None
    min_range_m: float
    max_range_m: float
    fov_rad: float | None


def read_beam(msg: Any, t_ns: int) -> RangeBeam | None:
    """``msg`` (a decoded DISTANCE_SENSOR) as a reading received at ``t_ns``; None for a sensor looking up
    or down; ``BeamRejected`` naming the field if it cannot be read."""
    quality = _whole(msg.signal_quality, "signal_quality")
    if quality == INVALID_SIGNAL:
        raise BeamRejected("signal_quality 1: the sensor says its reading is invalid")
    if not 0 <= quality <= 100:
        raise BeamRejected(f"signal_quality {quality} is not a percentage (0 unknown, 1 invalid, 100 best)")
    orientation = msg.orientation
    if isinstance(orientation, bool) or not isinstance(orientation, int):
        raise BeamRejected(f"orientation {orientation!r} is no MAV_SENSOR_ORIENTATION")
    try:
        seen = facing(orientation, msg.quaternion)
    except OrientationError as err:
        raise BeamRejected(f"orientation {orientation}: {err}") from err
    if abs(seen.tilt_rad) > MAX_TILT_RAD:
        return None
    to_level = math.cos(seen.tilt_rad)  # 1.0 exactly for a level sensor: its figures as they came
    min_cm = _distance(msg.min_distance, "min_distance")
    max_cm = _distance(msg.max_distance, "max_distance")
    if max_cm <= min_cm:
        raise BeamRejected(f"max_distance {max_cm:g} cm is not above min_distance {min_cm:g} cm")
    current_cm = _distance(msg.current_distance, "current_distance")
    # The width across the rover's horizontal plane: the sensor's own vertical one when it lies on its side.
    fov = (
        _fov(msg.vertical_fov, "vertical_fov")
        if seen.on_its_side
        else _fov(msg.horizontal_fov, "horizontal_fov")
    )
    if current_cm > max_cm:
        range_m: float | None = None
    elif current_cm >= min_cm:
        range_m = current_cm / 100.0
    elif current_cm >= 1.0:
        range_m = min_cm / 100.0  # too close to measure: at the nearest the sensor can tell
    else:
        raise BeamRejected(
            f"current_distance {current_cm:g} cm below min_distance {min_cm:g} cm is no reading, not a "
            "distance (a sensor too close to something reports at least 1 cm)"
        )
    if range_m is not None:
        range_m *= to_level
    min_m, max_m = min_cm / 100.0 * to_level, max_cm / 100.0 * to_level
    return RangeBeam(t_ns, int(msg.id), seen.bearing_rad, range_m, min_m, max_m, fov)


def _whole(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise BeamRejected(f"{name} {value!r} is not a whole number")
    return value


def _distance(value: Any, name: str) -> float:
    """A distance field in cm: a finite, non-negative number (the wire gives uint16; a caller may not)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise BeamRejected(f"{name} {value!r} is not a number")
    if not math.isfinite(value) or value < 0:
        raise BeamRejected(f"{name} {value!r} cm is not a finite, non-negative distance")
    return float(value)


def _fov(value: Any, name: str) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise BeamRejected(f"{name} {value!r} is not a number")
    if not (math.isfinite(value) and 0.0 <= value <= math.tau):
        raise BeamRejected(f"{name} {value!r} rad is not an angle in [0, 2 pi] (0: unknown)")
    return float(value) if value > 0.0 else None


def beam_message(
    mav: mavlink2.MAVLink,
    time_boot_ms: int,
    range_m: float | None,
    *,
    sensor_id: int,
    orientation: int,
    min_range_m: float,
    max_range_m: float,
    fov_rad: float,
    sensor_type: int = mavlink2.MAV_DISTANCE_SENSOR_LASER,
    quaternion: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
) -> Any:
    """A DISTANCE_SENSOR for one reading (None: nothing within ``max_range_m``, sent as ``max + 1`` cm);
    a range below ``min_range_m`` goes as it is, at least 1 cm (a too-close reading). ``fov_rad`` 0:
    unknown. ``quaternion`` (w, x, y, z): the mounting, with MAV_SENSOR_ROTATION_CUSTOM only."""
    min_cm = round(min_range_m * 100.0)
    max_cm = round(max_range_m * 100.0)
    current_cm = max_cm + 1 if range_m is None else min(max(round(range_m * 100.0), 1), max_cm)
    return mav.distance_sensor_encode(
        time_boot_ms % (1 << 32),
        min_cm,
        max_cm,
        current_cm,
        sensor_type,
        sensor_id,
        orientation,
        255,  # covariance: unknown (UINT8_MAX, as the field says)
        fov_rad,
        0.0,  # vertical_fov: unknown
        quaternion,
        0,  # signal_quality: unknown
    )
