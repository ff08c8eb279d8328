"""Where the lidar sits on the rover (``[perception]`` ``mount_*``): its returns land where they are.

Hand-computed: the rover's reference point at (1, 2) facing north (yaw 90 deg), the sensor 0.5 m in front
of it, at (1, 2.5), turned 90 deg to the rover's left, so facing west. A return 3 m straight ahead of the
sensor is at (-2, 2.5). Centre-mounted and facing forward, the same reading would put it at (1, 5).
"""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.obstacle_scan import SECTORS, read_scan
from logs.settings import ConfigError, parse_toml
from navigator.config import rover_config_from_table
from navigator.scan_clusters import ClusterSettings, detections
from navigator.scan_tracker import ScanTracker
from navigator.scan_tracker_config import ScanTrackerConfig
from navigator.sensor_mount import AT_CENTRE, SensorMount
from tests.navigator.scan_rig import scan_of

ROVER = (1.0, 2.0, math.pi / 2)
FORWARD_YAWED_LEFT = SensorMount(forward_m=0.5, yaw_rad=math.pi / 2)
AHEAD_OF_SENSOR = (-2.0, 2.5)


def _one_return(sector: int, frame: int, range_cm: int = 300) -> mavlink2.MAVLink_obstacle_distance_message:
    distances = [801] * SECTORS  # max_distance + 1: nothing
    distances[sector] = range_cm
    return mavlink2.MAVLink_obstacle_distance_message(
        0, mavlink2.MAV_DISTANCE_SENSOR_LASER, distances, 0, 10, 800, 5.0, 0.0, frame
    )


def _landed(msg: mavlink2.MAVLink_obstacle_distance_message, mount: SensorMount) -> tuple[float, float]:
    (found,) = detections(read_scan(msg, 0), *ROVER, ClusterSettings(), mount)
    ((x, y),) = found.points
    # A single return is the disc's near edge, as seen from the sensor.
    assert (found.edge_x, found.edge_y) == pytest.approx((x, y))
    return x, y


def test_a_body_frame_return_straight_ahead_of_a_mounted_sensor_lands_ahead_of_the_sensor() -> None:
    # Sector 0 of a BODY_FRD scan: the sensor's own forward direction.
    msg = _one_return(0, mavlink2.MAV_FRAME_BODY_FRD)
    assert _landed(msg, FORWARD_YAWED_LEFT) == pytest.approx(AHEAD_OF_SENSOR)
    assert _landed(msg, AT_CENTRE) == pytest.approx((1.0, 5.0))  # told nothing: ahead of the rover
    # Each part on its own: the offset moves the origin along the rover's heading; the yaw turns the ray.
    assert _landed(msg, SensorMount(forward_m=0.5)) == pytest.approx((1.0, 5.5))
    assert _landed(msg, SensorMount(yaw_rad=math.pi / 2)) == pytest.approx((-2.0, 2.0))
    assert _landed(msg, SensorMount(left_m=0.25)) == pytest.approx((0.75, 5.0))  # left of north: west


def test_a_north_aligned_return_turns_by_no_yaw_but_starts_at_the_sensor() -> None:
    # The same point, west of the sensor: 270 deg clockwise from north, sector 54 of a north-aligned scan.
    msg = _one_return(54, mavlink2.MAV_FRAME_LOCAL_NED)
    assert _landed(msg, FORWARD_YAWED_LEFT) == pytest.approx(AHEAD_OF_SENSOR)
    # The sensor's yaw does not turn a bearing counted from north...
    assert _landed(msg, SensorMount(yaw_rad=math.pi / 2)) == pytest.approx((-2.0, 2.0))
    # ...but its offset still moves the rays' origin, by the rover's heading (north here: +y).
    assert _landed(msg, SensorMount(forward_m=0.5)) == pytest.approx(AHEAD_OF_SENSOR)
    assert _landed(msg, AT_CENTRE) == pytest.approx((-2.0, 2.0))


def test_a_tracker_told_the_mount_finds_a_rock_the_mounted_lidar_sees_where_it_is() -> None:
    rock = ("rock", 5.0, 4.0, 0.5, 0.0, 0.0)
    pose = (1.0, 1.0, 0.3)
    mount = SensorMount(forward_m=0.6, left_m=-0.2, yaw_rad=math.radians(-30.0))

    def tracked(config: ScanTrackerConfig) -> tuple[float, float]:
        tracker = ScanTracker(config)
        for i in range(4):
            tracker.add(scan_of([rock], pose, i * 100_000_000, mount=mount), pose)
        (seen,) = tracker.poll()
        return seen.x, seen.y

    told = ScanTrackerConfig(mount_forward_m=0.6, mount_left_m=-0.2, mount_yaw_deg=-30.0)
    assert told.mount == mount
    x, y = tracked(told)
    assert math.hypot(x - 5.0, y - 4.0) < 0.15
    x, y = tracked(ScanTrackerConfig())  # not told: a rock somewhere else
    assert math.hypot(x - 5.0, y - 4.0) > 1.0


def test_the_mount_keys_are_read_and_bad_ones_named() -> None:
    text = "[perception]\nmount_forward_m = 0.45\nmount_left_m = -0.1\nmount_yaw_deg = 15.0\n"
    perception = rover_config_from_table(parse_toml(text, "<t>")).perception
    assert perception.mount == SensorMount(0.45, -0.1, math.radians(15.0))
    assert rover_config_from_table(parse_toml("", "<t>")).perception.mount == AT_CENTRE
    for bad in (
        "mount_yaw_deg = 190.0",
        "mount_forward_m = 6.0",
        "mount_left_m = nan",
        'mount_yaw_deg = "left"',
    ):
        with pytest.raises(ConfigError) as caught:
            rover_config_from_table(parse_toml(f"[perception]\n{bad}\n", "<t>"))
        assert caught.value.key == f"perception.{bad.split()[0]}"
