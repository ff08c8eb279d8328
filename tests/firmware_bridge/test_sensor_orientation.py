"""Where a sensor in each MAV_SENSOR_ORIENTATION looks, against scipy's rotations and ArduPilot's mountings;
MAV_SENSOR_ROTATION_CUSTOM from its quaternion; tilted sensors read at their horizontal distance."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2
from scipy.spatial.transform import Rotation

from firmware_bridge.distance_sensor import MAX_TILT_RAD, BeamRejected, read_beam
from firmware_bridge.sensor_orientation import (
    CUSTOM,
    OrientationError,
    euler_degrees,
    facing,
    forward_axis,
    side_axis,
)
from tests.firmware_bridge.test_distance_sensor import _message

NAMED = sorted(
    value
    for value, entry in mavlink2.enums["MAV_SENSOR_ORIENTATION"].items()
    if entry.name.startswith("MAV_SENSOR_ROTATION_") and value != CUSTOM
)


def test_every_named_orientation_is_read_from_its_name() -> None:
    assert len(NAMED) == 41  # 0..40 in today's dialect
    assert euler_degrees(mavlink2.MAV_SENSOR_ROTATION_ROLL_90_PITCH_180_YAW_90) == (90.0, 180.0, 90.0)
    assert euler_degrees(mavlink2.MAV_SENSOR_ROTATION_PITCH_315) == (0.0, 315.0, 0.0)
    assert euler_degrees(mavlink2.MAV_SENSOR_ROTATION_NONE) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("orientation", NAMED)
def test_each_named_orientation_looks_where_scipys_rotation_turns_the_x_axis(orientation: int) -> None:
    roll, pitch, yaw = euler_degrees(orientation)
    # Intrinsic z-y'-x'' (yaw, pitch, roll): the matrix Rz Ry Rx, ArduPilot's from_euler.
    rotation = Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True)
    assert np.allclose(forward_axis(orientation), rotation.apply([1.0, 0.0, 0.0]), atol=1e-9)
    assert np.allclose(side_axis(orientation), rotation.apply([0.0, 1.0, 0.0]), atol=1e-9)
    assert math.isclose(float(np.linalg.norm(forward_axis(orientation))), 1.0, abs_tol=1e-9)


@pytest.mark.parametrize(
    ("orientation", "bearing_deg", "tilt_deg"),
    [
        # Facts of ArduPilot's rotation table (AP_Math/rotations.h), as its Vector3::rotate maps (1, 0, 0).
        (mavlink2.MAV_SENSOR_ROTATION_YAW_90, -90.0, 0.0),  # right: RNGFND_ORIENT 2
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_90_YAW_45, -45.0, 0.0),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_90_PITCH_180, 180.0, 0.0),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_90_YAW_270, 90.0, 0.0),
        (mavlink2.MAV_SENSOR_ROTATION_PITCH_90, 0.0, 90.0),  # up: RNGFND_ORIENT 24
        (mavlink2.MAV_SENSOR_ROTATION_PITCH_270, 0.0, -90.0),  # down: RNGFND_ORIENT 25
        (mavlink2.MAV_SENSOR_ROTATION_PITCH_315, 0.0, -45.0),
    ],
)
def test_mountings_face_as_the_autopilot_means(orientation: int, bearing_deg: float, tilt_deg: float) -> None:
    seen = facing(orientation)
    assert math.degrees(seen.bearing_rad) == pytest.approx(bearing_deg, abs=1e-9)
    assert math.degrees(seen.tilt_rad) == pytest.approx(tilt_deg, abs=1e-9)


def test_the_one_mounting_whose_name_rounds_its_pitch_still_looks_steeply_up() -> None:
    # ArduPilot's Vector3::rotate maps x to (0.143, -0.332, -0.932) for it: 66.7 degrees left of the front,
    # 68.8 up. The name says pitch 68, read here as 67 and 68: far past the tilt limit either way.
    seen = facing(mavlink2.MAV_SENSOR_ROTATION_ROLL_90_PITCH_68_YAW_293)
    assert math.degrees(seen.bearing_rad) == pytest.approx(66.7, abs=0.5)
    assert math.degrees(seen.tilt_rad) == pytest.approx(68.8, abs=1.0)
    assert read_beam(_message(orientation=mavlink2.MAV_SENSOR_ROTATION_ROLL_90_PITCH_68_YAW_293), 0) is None


@pytest.mark.parametrize(
    ("orientation", "on_its_side"),
    [
        (mavlink2.MAV_SENSOR_ROTATION_NONE, False),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_180_YAW_90, False),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_90, True),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_270_YAW_45, True),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_90_PITCH_180_YAW_90, True),
    ],
)
def test_a_sensor_on_its_side_gives_its_vertical_field_of_view_as_the_width_across_the_ground(
    orientation: int, on_its_side: bool
) -> None:
    assert facing(orientation).on_its_side is on_its_side
    beam = read_beam(_message(orientation=orientation, fov=0.5, vertical_fov=0.1), 0)
    assert beam is not None and beam.fov_rad == pytest.approx(0.1 if on_its_side else 0.5)
    if on_its_side:  # its horizontal one is not read; an unknown vertical one is unknown
        unknown = read_beam(_message(orientation=orientation, fov=math.nan, vertical_fov=0.0), 0)
        assert unknown is not None and unknown.fov_rad is None
        with pytest.raises(BeamRejected, match="vertical_fov"):
            read_beam(_message(orientation=orientation, vertical_fov=-1.0), 0)


def test_a_custom_quaternion_knows_a_sensor_on_its_side() -> None:
    assert facing(CUSTOM, _quaternion(-45.0, 0.0, 90.0)).on_its_side
    assert not facing(CUSTOM, _quaternion(-45.0, 0.0, 180.0)).on_its_side


def _quaternion(yaw_deg: float, pitch_deg: float, roll_deg: float = 0.0) -> tuple[float, float, float, float]:
    x, y, z, w = Rotation.from_euler("ZYX", [yaw_deg, pitch_deg, roll_deg], degrees=True).as_quat()
    return float(w), float(x), float(y), float(z)


def test_a_custom_quaternion_gives_the_named_orientations_answer() -> None:
    for orientation in NAMED:
        roll, pitch, yaw = euler_degrees(orientation)
        custom, named = facing(CUSTOM, _quaternion(yaw, pitch, roll)), facing(orientation)
        expected = (named.bearing_rad, named.tilt_rad)
        assert (custom.bearing_rad, custom.tilt_rad) == pytest.approx(expected, abs=1e-9), orientation


def test_a_custom_quaternion_need_not_be_normalised_but_must_be_a_rotation() -> None:
    w, x, y, z = _quaternion(-30.0, 0.0)
    assert facing(CUSTOM, (2 * w, 2 * x, 2 * y, 2 * z)).bearing_rad == pytest.approx(math.radians(30.0))
    for bad in [(0.0, 0.0, 0.0, 0.0), (math.inf, 0.0, 0.0, 1.0), None, (1.0, 0.0, 0.0), ("a", 0, 0, 0)]:
        with pytest.raises(OrientationError, match="MAV_SENSOR_ROTATION_CUSTOM"):
            facing(CUSTOM, bad)


def test_a_slightly_tilted_sensor_reads_its_horizontal_distances() -> None:
    tilt_deg = 6.0  # a sonar turned 6 degrees down, a quarter to the left
    msg = _message(300, min_cm=20, max_cm=700, orientation=CUSTOM, quaternion=_quaternion(-90.0, -tilt_deg))
    beam = read_beam(msg, 0)
    assert beam is not None
    level = math.cos(math.radians(tilt_deg))
    assert beam.bearing_rad == pytest.approx(math.pi / 2)
    ranges = (beam.range_m, beam.min_range_m, beam.max_range_m)
    assert ranges == pytest.approx((3.0 * level, 0.2 * level, 7.0 * level))


def test_a_sensor_tilted_past_the_limit_is_not_used() -> None:
    limit_deg = math.degrees(MAX_TILT_RAD)
    for tilt_deg in (limit_deg + 0.5, -(limit_deg + 0.5)):
        assert read_beam(_message(orientation=CUSTOM, quaternion=_quaternion(0.0, tilt_deg)), 0) is None
    nearly_level = _message(orientation=CUSTOM, quaternion=_quaternion(0.0, limit_deg - 0.5))
    assert read_beam(nearly_level, 0) is not None


@settings(max_examples=300, deadline=None)
@given(st.tuples(*[st.floats(-1e6, 1e6)] * 4))
def test_any_finite_quaternion_faces_somewhere_or_is_refused(quaternion: tuple[float, ...]) -> None:
    try:
        seen = facing(CUSTOM, quaternion)
    except OrientationError:
        assert math.sqrt(sum(q * q for q in quaternion)) < 1e-6
        return
    assert -math.pi < seen.bearing_rad <= math.pi
    assert -math.pi / 2 <= seen.tilt_rad <= math.pi / 2
