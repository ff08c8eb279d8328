"""From lidar scans to tracked obstacles: discs where obstacles are, one id each, velocities for movers."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.obstacle_scan import SECTORS, read_scan
from logs.clock import NS_PER_S
from logs.settings import ConfigError, parse_toml
from navigator.config import rover_config_from_table
from navigator.odometry_frame import OdometryFrame
from navigator.perception import ObstacleObservation
from navigator.scan_clusters import ClusterSettings, detections
from navigator.scan_tracker import ScanTracker
from navigator.scan_tracker_config import ScanTrackerConfig
from navigator.scan_watch import ScanWatch
from tests.navigator.scan_rig import Disc, scan_of

SCAN_NS = 100_000_000  # 10 Hz


def _centres(discs: list[Disc], pose: tuple[float, float, float]) -> list[tuple[float, float, float]]:
    found = detections(scan_of(discs, pose, 0), *pose, ClusterSettings())
    return [(*d.centre(d.radius_m), d.radius_m) for d in found]


@pytest.mark.parametrize("yaw", [0.0, 0.7, -2.5])
def test_a_disc_is_found_where_it_is_whichever_way_the_rover_faces(yaw: float) -> None:
    ((x, y, radius),) = _centres([("rock", 5.0, 2.0, 0.6, 0.0, 0.0)], (1.0, 1.0, yaw))
    assert math.hypot(x - 5.0, y - 2.0) < 0.4
    assert 0.3 < radius < 1.0


def test_a_disc_straight_ahead_across_the_first_and_last_sector_is_one() -> None:
    # Straight ahead the disc fills sectors 71, 0 and 1: the run across the circle's seam is one object.
    found = _centres([("ahead", 4.0, 0.0, 0.5, 0.0, 0.0)], (0.0, 0.0, 0.0))
    assert len(found) == 1
    assert math.hypot(found[0][0] - 4.0, found[0][1]) < 0.3


def test_two_discs_apart_are_two_and_a_wall_is_a_row_of_pieces() -> None:
    apart = _centres([("a", 4.0, 3.0, 0.4, 0.0, 0.0), ("b", 4.0, -3.0, 0.4, 0.0, 0.0)], (0.0, 0.0, 0.0))
    assert len(apart) == 2
    wall = [(f"w{i}", 3.0, -2.0 + 0.2 * i, 0.15, 0.0, 0.0) for i in range(21)]  # 4 m of wall, 3 m ahead
    pieces = _centres(wall, (0.0, 0.0, 0.0))
    assert len(pieces) >= 3  # pieces of at most 1.5 m, not one disc 4 m wide
    assert all(radius <= 1.5 for _, _, radius in pieces)


def _track(
    discs_at: Callable[[float], list[Disc]],
    poses: list[tuple[float, float, float]],
    config: ScanTrackerConfig | None = None,
) -> ScanTracker:
    tracker = ScanTracker(config)
    for i, pose in enumerate(poses):
        t_ns = i * SCAN_NS
        tracker.add(scan_of(discs_at(t_ns * 1e-9), pose, t_ns, noise_m=0.02, seed=i), pose)
    return tracker


def test_a_static_obstacle_seen_from_a_driving_rover_is_one_static_track() -> None:
    poses = [(0.1 * i, 0.0, 0.0) for i in range(30)]  # 1 m/s along x for 3 s
    tracker = ScanTracker()
    reported = []
    for i, pose in enumerate(poses):
        t_ns = i * SCAN_NS
        tracker.add(scan_of([("rock", 6.0, 1.0, 0.6, 0.0, 0.0)], pose, t_ns, noise_m=0.02, seed=i), pose)
        reported += tracker.poll()
    assert {o.obstacle_id for o in reported} == {"scan-1"}
    assert not any(o.moving for o in reported)
    last = reported[-1]
    assert math.hypot(last.x - 6.0, last.y - 1.0) < 0.4
    assert len(reported) == len(poses) - 2  # reported from its third scan on (confirm_scans = 3)


def test_a_crossing_cart_is_tracked_as_moving_with_its_velocity() -> None:
    def cart(t_s: float) -> list[Disc]:
        return [("cart", 5.0, -3.0 + 0.8 * t_s, 0.5, 0.0, 0.8)]

    tracker = _track(cart, [(0.0, 0.0, 0.0)] * 25)
    (seen,) = tracker.poll()
    assert seen.moving
    assert seen.vy == pytest.approx(0.8, abs=0.2) and abs(seen.vx) < 0.2
    assert math.hypot(seen.x - 5.0, seen.y - (-3.0 + 0.8 * 2.4)) < 0.4


def test_a_track_out_of_sight_is_forgotten_and_a_scan_without_a_pose_only_counted() -> None:
    config = ScanTrackerConfig(forget_s=0.5)
    tracker = _track(lambda _t: [("rock", 3.0, 0.0, 0.4, 0.0, 0.0)], [(0.0, 0.0, 0.0)] * 5, config)
    assert tracker.track_count == 1
    empty = scan_of([], (0.0, 0.0, 0.0), 20 * SCAN_NS)
    tracker.add(empty, (0.0, 0.0, 0.0))
    assert tracker.track_count == 0
    tracker.add(empty, None)
    assert tracker.scans_without_pose == 1


def test_the_perception_table_is_read_and_a_bad_value_named() -> None:
    config = rover_config_from_table(parse_toml("[perception]\ngate_m = 2.5\nconfirm_scans = 2\n", "<t>"))
    assert config.perception.gate_m == 2.5 and config.perception.confirm_scans == 2
    with pytest.raises(ConfigError, match="moving_speed_mps"):
        rover_config_from_table(parse_toml("[perception]\nmoving_speed_mps = -1.0\n", "<t>"))
    with pytest.raises(ConfigError, match="gate"):
        rover_config_from_table(parse_toml("[perception]\ngate = 1.0\n", "<t>"))  # unknown key


def test_the_odometry_frame_dead_reckons_and_carries_the_fixes_in_its_offset() -> None:
    frame = OdometryFrame()
    frame.advance(0, 1.0, 0.0, (5.0, 2.0))
    assert (frame.x, frame.y) == (5.0, 2.0) and frame.offset() == (0.0, 0.0)
    step_ns = 400_000_000
    frame.advance(step_ns, 1.0, math.pi / 2, (5.6, 2.4))  # a fix 0.3 m off where it drove
    # Half a turn on average: 0.4 m along 45 degrees.
    along = 0.4 * math.sqrt(0.5)
    assert frame.x == pytest.approx(5.0 + along) and frame.y == pytest.approx(2.0 + along)
    assert frame.offset() == pytest.approx((5.6 - frame.x, 2.4 - frame.y))
    # A gap (scans stopped): not dead-reckoned across; the frame moves as the fixes did, the offset holds.
    offset = frame.offset()
    frame.advance(step_ns + 700_000_000, 1.0, 0.0, (9.0, 2.4))
    assert frame.offset() == pytest.approx(offset) and frame.x == pytest.approx(9.0 - offset[0])
    # Heading west through the wrap at +-pi: 0.1 m west, not east (the mean of the two numbers is 0).
    frame.advance(step_ns + 800_000_000, 1.0, math.pi - 0.01, (9.0, 2.4))
    x, y = frame.x, frame.y
    frame.advance(step_ns + 900_000_000, 1.0, -math.pi + 0.01, (9.0, 2.4))
    assert frame.x == pytest.approx(x - 0.1) and frame.y == pytest.approx(y, abs=1e-9)


def _static_rock_track(jumpy_fixes: bool, dead_reckoned: bool) -> list[ObstacleObservation]:
    """A rock 6 m ahead seen from a rover driving at 0.5 m/s whose fused position jumps by up to 0.3 m
    every fifth scan, as with GPS corrections; tracked on the fused pose or in the odometry frame."""
    tracker, frame, reported = ScanTracker(), OdometryFrame(), []
    rng = np.random.default_rng(7)
    jump = (0.0, 0.0)
    for i in range(40):
        t_ns = i * SCAN_NS
        true_pose = (0.05 * i, 0.0, 0.0)
        if jumpy_fixes and i % 5 == 0:
            jump = (float(rng.uniform(-0.3, 0.3)), float(rng.uniform(-0.3, 0.3)))
        fused = (true_pose[0] + jump[0], true_pose[1] + jump[1])
        scan = scan_of([("rock", 6.0, 0.5, 0.6, 0.0, 0.0)], true_pose, t_ns, noise_m=0.02, seed=i)
        if dead_reckoned:
            frame.advance(t_ns, 0.5, 0.0, fused)
            tracker.add(scan, (frame.x, frame.y, 0.0), frame.offset())
        else:
            tracker.add(scan, (*fused, 0.0))
        reported += tracker.poll()
    return reported


def test_a_static_rock_stays_static_when_tracked_in_the_odometry_frame() -> None:
    # On the jumpy fused pose it seems to move (the failure this frame mends) ...
    assert any(o.moving for o in _static_rock_track(jumpy_fixes=True, dead_reckoned=False))
    # ... dead-reckoned it does not, and it is reported on the map (the offset moves it there).
    reported = _static_rock_track(jumpy_fixes=True, dead_reckoned=True)
    assert reported and not any(o.moving for o in reported)
    assert math.hypot(reported[-1].x - 6.0, reported[-1].y - 0.5) < 0.5


def test_a_lidar_gone_quiet_is_said_once_and_its_return_too() -> None:
    events: list[tuple[str, str, str]] = []
    watch = ScanWatch(lambda kind, severity, detail: events.append((kind, severity, detail)))
    watch.check(10 * NS_PER_S)  # no scan yet: nothing to miss (a rover without a lidar)
    for i in range(10):
        watch.scan(i * SCAN_NS)
    watch.check(9 * SCAN_NS + NS_PER_S)  # exactly 1 s: not yet
    assert events == []
    for t_ns in (9 * SCAN_NS + NS_PER_S + 1, 5 * NS_PER_S):
        watch.check(t_ns)
    ((kind, severity, detail),) = events
    assert (kind, severity) == ("perception_lost", "warning") and "every 0.10 s" in detail
    watch.scan(6 * NS_PER_S)
    assert events[-1][:2] == ("perception_back", "info") and "after 5.1 s" in events[-1][2]


def test_a_slow_lidar_is_given_three_of_its_periods() -> None:
    events: list[str] = []
    watch = ScanWatch(lambda kind, _severity, _detail: events.append(kind))
    for i in range(4):
        watch.scan(i * 2 * NS_PER_S)  # 0.5 Hz
    watch.check(6 * NS_PER_S + 5 * NS_PER_S)  # 5 s after the last: within 3 x 2 s
    assert events == []
    watch.check(6 * NS_PER_S + 7 * NS_PER_S)
    assert events == ["perception_lost"]


@settings(max_examples=60, deadline=None)
@given(
    sweeps=st.lists(
        st.lists(st.integers(0, 65535), min_size=SECTORS, max_size=SECTORS), min_size=1, max_size=6
    ),
    increment=st.sampled_from([1.0, 2.5, 5.0]),
    yaw=st.floats(-math.pi, math.pi),
)
def test_any_scans_give_finite_discs_and_no_exception(
    sweeps: list[list[int]], increment: float, yaw: float
) -> None:
    tracker = ScanTracker()
    for i, distances in enumerate(sweeps):
        msg = mavlink2.MAVLink_obstacle_distance_message(
            0, 0, distances, 0, 10, 800, increment, -90.0, mavlink2.MAV_FRAME_BODY_FRD
        )
        tracker.add(read_scan(msg, i * SCAN_NS), (1.0, 2.0, yaw), (0.5, -0.5))
        for seen in tracker.poll():
            values = (seen.x, seen.y, seen.radius_m, seen.vx, seen.vy)
            assert all(map(math.isfinite, values)) and seen.radius_m > 0.0
