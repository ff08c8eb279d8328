"""Where a sensor mounted in a MAV_SENSOR_ORIENTATION looks: its forward axis in the vehicle's body frame.

MAVLink's MAV_SENSOR_ORIENTATION (DISTANCE_SENSOR's ``orientation``) names each mounting by Euler angles
in degrees, ``ROLL_<r>_PITCH_<p>_YAW_<y>`` with the absent ones 0: the sensor's frame is turned by roll
about x, then pitch about y, then yaw about z, in the body frame FRD (x forward, y right, z down), the
rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` as ArduPilot's rotation table and ``Vector3::rotate`` apply it.
The angles are read from the enum's names, so every named orientation is covered, the ones pymavlink adds
later included. MAV_SENSOR_ROTATION_CUSTOM takes the message's quaternion instead (w, x, y, z, the sensor
frame in the body frame; all zeros: invalid, as the field says).

A sensor looks along its own x axis: ``forward_axis`` is where that axis points. Roll turns a sensor
about that axis, so a sensor on its side (ROLL_90_YAW_45) looks where YAW_45 does; pitch tilts it up
(positive) or down. ``facing`` gives the horizontal direction and the tilt a rover's perception needs,
and whether the sensor lies on its side (then its vertical field of view is the one across the ground).

ArduPilot's ROLL_90_PITCH_68_YAW_293 is pitched 68.8 degrees, not the name's 68; the name's angle is used
here (that sensor looks 68 degrees up either way: not an obstacle sensor for a rover).
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import common as mavlink2

CUSTOM = mavlink2.MAV_SENSOR_ROTATION_CUSTOM
_ANGLE = re.compile(r"(ROLL|PITCH|YAW)_(\d+)")
# Axis components are rounded to this many decimals, so 45-degree steps give exact bearings (cos 90
# degrees is 6e-17 in floating point, not 0, which would put YAW_180 at -pi instead of pi).
_DECIMALS = 12


class OrientationError(ValueError):
    """An orientation this module cannot place; the message says why."""


@dataclass(frozen=True)
class Facing:
    """Where a sensor looks: ``bearing_rad`` counter-clockwise from the vehicle's front in (-pi, pi] (0
    for a sensor looking straight up or down), ``tilt_rad`` above the horizontal (negative: down).
    ``on_its_side``: the sensor's own y axis (across its beam, its "horizontal") stands closer to the
    vehicle's vertical than to its horizontal plane (a roll near 90 or 270 degrees), so what the sensor
    calls its vertical field of view spans the vehicle's horizontal plane."""

    bearing_rad: float
    tilt_rad: float
    on_its_side: bool = False


def euler_degrees(orientation: int) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in degrees of a named MAV_SENSOR_ORIENTATION other than CUSTOM."""
    entry = mavlink2.enums["MAV_SENSOR_ORIENTATION"].get(orientation)
    if entry is None or orientation == CUSTOM or not entry.name.startswith("MAV_SENSOR_ROTATION_"):
        raise OrientationError(f"{orientation!r} is no named MAV_SENSOR_ORIENTATION")
    angles = {"ROLL": 0.0, "PITCH": 0.0, "YAW": 0.0}
    for axis, degrees in _ANGLE.findall(entry.name):
        angles[axis] = float(degrees)
    return angles["ROLL"], angles["PITCH"], angles["YAW"]


Axis = tuple[float, float, float]


def forward_axis(orientation: int, quaternion: Any = None) -> Axis:
    """The unit vector (FRD) a sensor mounted in ``orientation`` looks along; ``quaternion`` (w, x, y,
    z) is read for MAV_SENSOR_ROTATION_CUSTOM only. ``OrientationError`` for an unknown orientation or
    a custom one without a usable quaternion."""
    return _axes(orientation, quaternion)[0]


def side_axis(orientation: int, quaternion: Any = None) -> Axis:
    """The unit vector (FRD) the sensor's own y axis points along: ``forward_axis``'s companion, the
    second column of the same rotation."""
    return _axes(orientation, quaternion)[1]


def facing(orientation: int, quaternion: Any = None) -> Facing:
    """``forward_axis`` as a bearing (counter-clockwise, our convention; FRD's y is to the right) and a
    tilt above the horizontal; whether the sensor is on its side (``side_axis``)."""
    if orientation == CUSTOM:
        return _facing_along(*_axes(orientation, quaternion))
    return _named_facing(orientation)


@functools.cache
def _named_facing(orientation: int) -> Facing:
    # Every rangefinder reading asks; the answer for a named orientation never changes.
    return _facing_along(*_axes(orientation, None))


def _axes(orientation: int, quaternion: Any) -> tuple[Axis, Axis]:
    """The first two columns of the sensor's rotation into the body frame: where it turns the x axis (the
    beam; rounded, see ``_DECIMALS``) and the y axis."""
    if orientation == CUSTOM:
        w, x, y, z = _unit_quaternion(quaternion)
        forward = (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y))
        side = (2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x))
    else:
        roll, pitch, yaw = (math.radians(angle) for angle in euler_degrees(orientation))
        sr, cr, sp, cp, sy, cy = (
            math.sin(roll),
            math.cos(roll),
            math.sin(pitch),
            math.cos(pitch),
            math.sin(yaw),
            math.cos(yaw),
        )
        # Rz(yaw) Ry(pitch) Rx(roll) applied to (1, 0, 0) (the roll leaves it where it is) and (0, 1, 0).
        forward = (cp * cy, cp * sy, -sp)
        side = (cy * sp * sr - sy * cr, sy * sp * sr + cy * cr, cp * sr)
    rounded = (
        round(forward[0], _DECIMALS) + 0.0,
        round(forward[1], _DECIMALS) + 0.0,
        round(forward[2], _DECIMALS) + 0.0,
    )
    return rounded, side


def _facing_along(axis: Axis, side: Axis) -> Facing:
    x, y, z = axis
    horizontal = math.hypot(x, y)
    tilt = math.atan2(-z, horizontal)
    on_its_side = abs(side[2]) > math.hypot(side[0], side[1])
    if horizontal == 0.0:
        return Facing(0.0, tilt, on_its_side)
    bearing = math.atan2(-y, x)
    return Facing(math.pi if bearing == -math.pi else bearing, tilt, on_its_side)


def _unit_quaternion(quaternion: Any) -> tuple[float, float, float, float]:
    try:
        w, x, y, z = (float(part) for part in quaternion)
    except (TypeError, ValueError, OverflowError) as err:
        raise OrientationError(
            f"MAV_SENSOR_ROTATION_CUSTOM needs a quaternion of four numbers, got {quaternion!r}"
        ) from err
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if not math.isfinite(norm) or norm < 1e-6:
        # All zeros is the field's "invalid" (a sender that does not fill it, or a MAVLink 1 frame).
        raise OrientationError(
            f"MAV_SENSOR_ROTATION_CUSTOM with quaternion {tuple(quaternion)!r}: not a rotation "
            "(all zeros: the sender left it invalid)"
        )
    return w / norm, x / norm, y / norm, z / norm
