"""OBSTACLE_DISTANCE on the companion's MAVLink link: read in our conventions, bad ones counted, refused."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_link import MavlinkLink
from firmware_bridge.mavlink_transport import memory_pipe_pair
from firmware_bridge.obstacle_scan import (
    SECTORS,
    UNMEASURED_CM,
    ObstacleScan,
    ScanRejected,
    read_scan,
    scan_message,
)
from logs.clock import SimClock
from logs.sink import MemorySink


def _message(
    distances: list[int],
    *,
    increment_f: float = 5.0,
    angle_offset: float = 0.0,
    frame: int = mavlink2.MAV_FRAME_BODY_FRD,
    min_cm: int = 10,
    max_cm: int = 800,
) -> mavlink2.MAVLink_obstacle_distance_message:
    return mavlink2.MAVLink_obstacle_distance_message(
        0, mavlink2.MAV_DISTANCE_SENSOR_LASER, distances, 0, min_cm, max_cm, increment_f, angle_offset, frame
    )


def _nothing() -> list[int]:
    return [801] * SECTORS  # max_distance + 1: nothing in any sector


def test_a_return_to_the_right_is_a_negative_angle_in_the_body_frame() -> None:
    distances = _nothing()
    distances[18] = 250  # 18 x 5 deg clockwise from the front: straight to the right
    scan = read_scan(_message(distances), 7)
    hits = [(angle, r) for angle, r in scan.rays if r is not None]
    assert hits == [(pytest.approx(-math.pi / 2), 2.5)]
    assert scan.body_frame and scan.full_circle and scan.t_ns == 7
    assert len(scan.rays) == SECTORS  # every sector measured: 71 of them saw nothing
    assert scan.max_range_m == 8.0 and scan.min_range_m == 0.1


def test_a_north_aligned_scan_counts_from_east() -> None:
    distances = _nothing()
    distances[0] = 300  # north
    scan = read_scan(_message(distances, frame=mavlink2.MAV_FRAME_LOCAL_NED), 0)
    ((angle, distance),) = [ray for ray in scan.rays if ray[1] is not None]
    assert not scan.body_frame
    assert angle == pytest.approx(math.pi / 2) and distance == 3.0


def test_unmeasured_sectors_are_left_out_and_too_near_ones_touch() -> None:
    distances = _nothing()
    distances[3] = UNMEASURED_CM
    distances[4] = 5  # below min_distance (10 cm): an obstacle at the sensor's nearest, not nothing
    distances[5] = 0  # the spec's "practically touching the sensor"
    scan = read_scan(_message(distances, increment_f=2.5, angle_offset=-90.0), 0)
    assert len(scan.rays) == SECTORS - 1
    assert not scan.full_circle  # 72 x 2.5 deg: the front half only
    assert scan.rays[0][0] == pytest.approx(math.pi / 2)  # -90 deg clockwise: the left
    assert [r for _, r in scan.rays if r is not None] == [0.1, 0.1]


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ({"frame": mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT}, "frame"),
        ({"increment_f": 0.0}, "increment"),
        ({"increment_f": float("nan")}, "increment"),
        ({"increment_f": 10.0}, "overlap"),
        ({"angle_offset": float("inf")}, "angle_offset"),
        ({"min_cm": 500, "max_cm": 400}, "max_distance"),
    ],
)
def test_a_scan_that_cannot_be_read_is_refused_naming_why(change: dict, named: str) -> None:
    with pytest.raises(ScanRejected, match=named):
        read_scan(_message(_nothing(), **change), 0)


def test_the_link_delivers_scans_and_counts_refused_ones_without_raising() -> None:
    companion_end, autopilot_end = memory_pipe_pair()
    link = MavlinkLink(companion_end, SimClock(1_000), MemorySink())
    sender = mavlink2.MAVLink(autopilot_end, 1, mavlink2.MAV_COMP_ID_OBSTACLE_AVOIDANCE)
    ranges: list[float | None] = [None] * SECTORS
    ranges[0] = 4.0
    sender.send(
        scan_message(
            sender, 5, ranges, increment_deg=5.0, angle_offset_deg=0.0, min_range_m=0.1, max_range_m=8.0
        )
    )
    sender.send(_message(_nothing(), increment_f=0.0))
    readings = link.poll()
    scans = [r for r in readings if isinstance(r, ObstacleScan)]
    assert len(scans) == 1 and link.counters.scans_rejected == 1 and link.counters.scans == 1
    assert [r for r in scans[0].rays if r[1] is not None] == [(0.0, 4.0)]


def test_scan_message_clamps_ranges_to_what_the_sensor_reports() -> None:
    mav = mavlink2.MAVLink(None, 1, 1)
    ranges: list[float | None] = [None] * SECTORS
    ranges[1], ranges[2] = 0.01, 99.0
    msg = scan_message(
        mav, 0, ranges, increment_deg=5.0, angle_offset_deg=0.0, min_range_m=0.05, max_range_m=8.0
    )
    assert msg.distances[0] == 801 and msg.distances[1] == 5 and msg.distances[2] == 800
    with pytest.raises(ValueError, match="72"):
        scan_message(
            mav, 0, [None], increment_deg=5.0, angle_offset_deg=0.0, min_range_m=0.05, max_range_m=8.0
        )


@settings(max_examples=200, deadline=None)
@given(
    distances=st.lists(st.integers(0, 65535), min_size=SECTORS, max_size=SECTORS),
    increment=st.integers(0, 255),
    increment_f=st.floats(width=32),
    angle_offset=st.floats(width=32),
    frame=st.integers(0, 255),
    min_cm=st.integers(0, 65535),
    max_cm=st.integers(0, 65535),
)
def test_any_field_values_give_a_scan_or_a_refusal(
    distances: list[int],
    increment: int,
    increment_f: float,
    angle_offset: float,
    frame: int,
    min_cm: int,
    max_cm: int,
) -> None:
    msg = mavlink2.MAVLink_obstacle_distance_message(
        0, 0, distances, increment, min_cm, max_cm, increment_f, angle_offset, frame
    )
    try:
        scan = read_scan(msg, 0)
    except ScanRejected:
        return
    assert all(math.isfinite(angle) and (r is None or 0.0 <= r <= 655.35) for angle, r in scan.rays)
