"""DISTANCE_SENSOR on the companion's MAVLink link: one rangefinder reading in our conventions, bad ones
counted and refused, up- and down-looking ones counted as not used."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.distance_sensor import (
    ORIENTATION_OF_YAW_DEG,
    BeamRejected,
    RangeBeam,
    beam_message,
    read_beam,
)
from firmware_bridge.mavlink_link import MavlinkLink
from firmware_bridge.mavlink_transport import memory_pipe_pair
from firmware_bridge.sensor_orientation import facing
from logs.clock import NS_PER_S, SimClock
from logs.sink import MemorySink
from logs.topics import MAVLINK_STATS

ROTATION = mavlink2.MAV_SENSOR_ROTATION_NONE
CUSTOM = mavlink2.MAV_SENSOR_ROTATION_CUSTOM


def _message(
    current_cm: Any = 250,
    *,
    min_cm: Any = 20,
    max_cm: Any = 700,
    orientation: Any = ROTATION,
    sensor_id: int = 3,
    fov: Any = 0.0,
    quality: Any = 0,
    quaternion: Any = (0.0, 0.0, 0.0, 0.0),
    vertical_fov: Any = 0.0,
) -> mavlink2.MAVLink_distance_sensor_message:
    return mavlink2.MAVLink_distance_sensor_message(
        0,
        min_cm,
        max_cm,
        current_cm,
        mavlink2.MAV_DISTANCE_SENSOR_ULTRASOUND,
        sensor_id,
        orientation,
        255,
        fov,
        vertical_fov,
        quaternion,
        quality,
    )


def _read(msg: Any) -> RangeBeam:
    beam = read_beam(msg, 9)
    assert beam is not None
    return beam


def test_a_forward_reading_in_metres_from_the_front() -> None:
    beam = _read(_message(250, fov=0.5, quality=80))
    assert beam == RangeBeam(9, 3, 0.0, 2.5, 0.2, 7.0, 0.5)


@pytest.mark.parametrize(
    ("orientation", "degrees_ccw"),
    [
        (mavlink2.MAV_SENSOR_ROTATION_NONE, 0.0),
        (mavlink2.MAV_SENSOR_ROTATION_YAW_45, -45.0),  # front right
        (mavlink2.MAV_SENSOR_ROTATION_YAW_90, -90.0),  # right (ArduPilot RNGFND_ORIENT 2, PX4 RIGHT_FACING)
        (mavlink2.MAV_SENSOR_ROTATION_YAW_135, -135.0),
        (mavlink2.MAV_SENSOR_ROTATION_YAW_180, 180.0),  # back
        (mavlink2.MAV_SENSOR_ROTATION_YAW_225, 135.0),
        (mavlink2.MAV_SENSOR_ROTATION_YAW_270, 90.0),  # left (ArduPilot 6, PX4 LEFT_FACING)
        (mavlink2.MAV_SENSOR_ROTATION_YAW_315, 45.0),  # front left
        # Upside down: the roll leaves the forward axis alone (ArduPilot's Vector3::rotate).
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_180, 0.0),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_180_YAW_90, -90.0),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_180_YAW_315, 45.0),
        (mavlink2.MAV_SENSOR_ROTATION_PITCH_180, 180.0),
        (mavlink2.MAV_SENSOR_ROTATION_PITCH_180_YAW_90, 90.0),  # rotate() maps x to -y: left
        (mavlink2.MAV_SENSOR_ROTATION_PITCH_180_YAW_270, -90.0),
        # On its side: a roll of 90 or 270 turns the sensor about the axis it looks along.
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_90, 0.0),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_90_YAW_45, -45.0),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_270_YAW_135, -135.0),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_90_YAW_270, 90.0),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_90_PITCH_180, 180.0),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_270_PITCH_180, 180.0),
        (mavlink2.MAV_SENSOR_ROTATION_ROLL_90_PITCH_180_YAW_90, 90.0),  # back, then a quarter clockwise
    ],
)
def test_every_horizontal_orientation_has_its_bearing(orientation: int, degrees_ccw: float) -> None:
    beam = _read(_message(orientation=orientation))
    assert beam.bearing_rad == pytest.approx(math.radians(degrees_ccw))
    assert -math.pi < beam.bearing_rad <= math.pi


def test_the_simulator_names_each_yaw_by_its_orientation() -> None:
    for yaw_deg, orientation in ORIENTATION_OF_YAW_DEG.items():
        # clockwise there, counter-clockwise here
        turned = facing(orientation).bearing_rad + math.radians(yaw_deg)
        assert math.remainder(turned, math.tau) == pytest.approx(0.0, abs=1e-12)


def test_nothing_within_range_is_above_max_distance() -> None:
    assert _read(_message(701)).range_m is None
    assert _read(_message(65535)).range_m is None
    assert _read(_message(700)).range_m == 7.0  # at max_distance: an obstacle there


def test_too_close_to_measure_is_an_obstacle_at_the_minimum() -> None:
    assert _read(_message(5, min_cm=20)).range_m == 0.2
    assert _read(_message(1, min_cm=20)).range_m == 0.2
    assert _read(_message(0, min_cm=0)).range_m == 0.0  # a sensor that measures down to 0: touching


@pytest.mark.parametrize(
    "orientation",
    [
        mavlink2.MAV_SENSOR_ROTATION_PITCH_90,
        mavlink2.MAV_SENSOR_ROTATION_PITCH_270,
        mavlink2.MAV_SENSOR_ROTATION_ROLL_180_PITCH_270,
        mavlink2.MAV_SENSOR_ROTATION_PITCH_315,  # 45 degrees down: a cliff sensor
        mavlink2.MAV_SENSOR_ROTATION_ROLL_90_PITCH_315,
        mavlink2.MAV_SENSOR_ROTATION_ROLL_90_PITCH_68_YAW_293,  # 68 degrees up
    ],
)
def test_up_and_down_sensors_are_not_obstacle_sensors(orientation: int) -> None:
    assert read_beam(_message(orientation=orientation), 0) is None


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ({"quality": 1}, "invalid"),
        ({"quality": 101}, "percentage"),
        ({"orientation": mavlink2.MAV_SENSOR_ROTATION_CUSTOM}, "invalid"),  # its quaternion all zeros
        ({"orientation": CUSTOM, "quaternion": (math.nan, 0, 0, 1)}, "quaternion"),
        ({"orientation": CUSTOM, "quaternion": (1.0, 0.0)}, "four numbers"),
        ({"orientation": 77}, "no named MAV_SENSOR_ORIENTATION"),
        ({"orientation": mavlink2.MAV_SENSOR_ORIENTATION_ENUM_END}, "no named MAV_SENSOR_ORIENTATION"),
        ({"orientation": 2.0}, "no MAV_SENSOR_ORIENTATION"),
        ({"min_cm": 500, "max_cm": 400}, "max_distance"),
        ({"min_cm": 0, "max_cm": 0}, "max_distance"),
        ({"min_cm": float("nan")}, "min_distance"),
        ({"max_cm": float("inf")}, "max_distance"),
        ({"current_cm": -1}, "current_distance"),
        ({"current_cm": "far"}, "current_distance"),
        ({"current_cm": 0, "min_cm": 20}, "no reading"),
        ({"fov": float("nan")}, "horizontal_fov"),
        ({"fov": -0.1}, "horizontal_fov"),
        ({"fov": 7.0}, "horizontal_fov"),
    ],
)
def test_a_reading_that_cannot_be_read_is_refused_naming_why(change: dict[str, Any], named: str) -> None:
    with pytest.raises(BeamRejected, match=named):
        read_beam(_message(**change), 0)


def test_beam_message_says_nothing_above_max_and_keeps_too_close_readings() -> None:
    mav = mavlink2.MAVLink(None, 1, 1)

    def sent(range_m: float | None) -> int:
        msg = beam_message(
            mav, 0, range_m, sensor_id=1, orientation=2, min_range_m=0.2, max_range_m=7.0, fov_rad=0.3
        )
        return int(msg.current_distance)

    assert sent(None) == 701 and sent(99.0) == 700 and sent(0.05) == 5 and sent(0.0) == 1
    beam = _read(
        beam_message(mav, 0, 3.0, sensor_id=4, orientation=6, min_range_m=0.2, max_range_m=7.0, fov_rad=0.3)
    )
    assert (beam.sensor_id, beam.range_m, beam.bearing_rad) == (4, 3.0, pytest.approx(math.pi / 2))
    assert beam.fov_rad == pytest.approx(0.3)


def test_the_link_delivers_beams_counts_the_rest_and_reports_them() -> None:
    companion_end, autopilot_end = memory_pipe_pair()
    clock = SimClock(1_000)
    sink = MemorySink()
    link = MavlinkLink(companion_end, clock, sink)
    sender = mavlink2.MAVLink(autopilot_end, 1, 1)
    sender.send(_message(300))
    sender.send(_message(300, quality=1))  # refused
    sender.send(_message(300, orientation=mavlink2.MAV_SENSOR_ROTATION_PITCH_270))  # not used
    readings = link.poll()
    assert [r for r in readings if isinstance(r, RangeBeam)] == [
        RangeBeam(1_000, 3, 0.0, 3.0, 0.2, 7.0, None)
    ]
    counters = link.counters
    assert (counters.beams, counters.beams_rejected, counters.beams_unused) == (1, 1, 1)
    clock.advance(NS_PER_S)
    link.poll()
    (stats,) = sink.on(MAVLINK_STATS)
    assert (stats["beams"], stats["beams_rejected"], stats["beams_unused"]) == (1, 1, 1)


def test_a_custom_mounting_reaches_the_rover_through_the_link_with_its_quaternion() -> None:
    """The quaternion is a MAVLink 2 extension field: it must survive packing, the wire and parsing."""
    companion_end, autopilot_end = memory_pipe_pair()
    link = MavlinkLink(companion_end, SimClock(0), MemorySink())
    sender = mavlink2.MAVLink(autopilot_end, 1, 1)
    half = math.radians(-30.0) / 2.0  # 30 degrees counter-clockwise seen from above: yaw -30 in FRD
    custom = mavlink2.MAV_SENSOR_ROTATION_CUSTOM
    sender.send(_message(300, orientation=custom, quaternion=(math.cos(half), 0.0, 0.0, math.sin(half))))
    (beam,) = [r for r in link.poll() if isinstance(r, RangeBeam)]
    assert beam.bearing_rad == pytest.approx(math.radians(30.0), abs=1e-6)
    assert beam.range_m == pytest.approx(3.0)


def test_a_link_without_rangefinders_reports_no_beam_counts() -> None:
    companion_end, _ = memory_pipe_pair()
    clock = SimClock(0)
    sink = MemorySink()
    link = MavlinkLink(companion_end, clock, sink)
    clock.advance(NS_PER_S)
    link.poll()
    (stats,) = sink.on(MAVLINK_STATS)
    assert "beams" not in stats and "scans" in stats


@settings(max_examples=300, deadline=None)
@given(
    current_cm=st.one_of(st.integers(-5, 70000), st.floats(), st.none(), st.text(max_size=2)),
    min_cm=st.one_of(st.integers(0, 65535), st.floats()),
    max_cm=st.one_of(st.integers(0, 65535), st.floats()),
    orientation=st.one_of(st.integers(-1, 255), st.just(mavlink2.MAV_SENSOR_ROTATION_CUSTOM), st.none()),
    fov=st.one_of(st.floats(), st.integers(-3, 10)),
    quality=st.one_of(st.integers(-3, 300), st.floats(), st.booleans()),
    quaternion=st.one_of(
        st.tuples(st.floats(), st.floats(), st.floats(), st.floats()),
        st.lists(st.one_of(st.integers(), st.floats(), st.text(max_size=1)), max_size=5),
        st.none(),
    ),
)
def test_any_field_values_give_a_reading_a_none_or_a_refusal(
    current_cm: Any, min_cm: Any, max_cm: Any, orientation: Any, fov: Any, quality: Any, quaternion: Any
) -> None:
    msg = _message(
        current_cm,
        min_cm=min_cm,
        max_cm=max_cm,
        orientation=orientation,
        fov=fov,
        quality=quality,
        quaternion=quaternion,
    )
    try:
        beam = read_beam(msg, 0)
    except BeamRejected as error:
        assert str(error)
        return
    if beam is None:
        return
    assert -math.pi < beam.bearing_rad <= math.pi
    assert 0.0 <= beam.min_range_m < beam.max_range_m and math.isfinite(beam.max_range_m)
    assert beam.range_m is None or beam.min_range_m <= beam.range_m <= beam.max_range_m
    assert beam.fov_rad is None or 0.0 < beam.fov_rad <= math.tau
