"""Obstacles from rangefinders' beams: one disc per beam that saw something, placed by the sensor's mount,
tracked with the lidar's tracks without disturbing them; each rangefinder watched on its own."""

from __future__ import annotations

import itertools
import logging
import math

import pytest

from firmware_bridge.distance_sensor import RangeBeam
from logs.clock import NS_PER_S
from logs.settings import ConfigError, parse_toml
from navigator.beam_detections import BeamPlacer, RangefinderMount, beam_detection
from navigator.config import rover_config_from_table
from navigator.perception import ObstacleObservation
from navigator.scan_tracker import ScanTracker
from navigator.scan_tracker_config import ScanTrackerConfig
from navigator.scan_watch import RangefinderWatch
from tests.navigator.scan_rig import beams_of, scan_of

READ_NS = NS_PER_S // 10
RING = tuple(RangefinderMount(i) for i in range(5))


def _beam(
    range_m: float | None, *, bearing: float = 0.0, fov: float | None = None, sensor: int = 0
) -> RangeBeam:
    return RangeBeam(0, sensor, bearing, range_m, 0.2, 7.0, fov)


def test_a_narrow_beam_is_a_small_disc_just_behind_its_echo() -> None:
    found = beam_detection(_beam(3.0), 0.0, 0.0, 0.0, RangefinderMount(0), 0.1)
    assert found is not None
    assert (found.edge_x, found.edge_y, found.radius_m) == pytest.approx((3.0, 0.0, 0.1))
    assert found.centre(found.radius_m) == pytest.approx((3.1, 0.0))


@pytest.mark.parametrize("fov_deg", [10.0, 30.0, 60.0, 90.0])
def test_a_wide_beam_is_the_smallest_disc_holding_its_arc(fov_deg: float) -> None:
    half = math.radians(fov_deg) / 2.0
    found = beam_detection(_beam(4.0, fov=2.0 * half), 0.0, 0.0, 0.0, RangefinderMount(0), 0.1)
    assert found is not None
    assert found.radius_m == pytest.approx(4.0 * math.sin(half))
    cx, cy = found.centre(found.radius_m)
    for t in [-1.0, -0.5, 0.0, 0.5, 1.0]:  # anywhere on the arc the echo may have come from
        ax, ay = 4.0 * math.cos(t * half), 4.0 * math.sin(t * half)
        assert math.hypot(ax - cx, ay - cy) <= found.radius_m + 1e-9
    assert found.edge_x >= -1e-9  # never back over the sensor


def test_a_cone_wider_than_90_degrees_is_taken_as_90_and_nothing_seen_is_no_disc() -> None:
    wide = beam_detection(_beam(2.0, fov=math.radians(150.0)), 0.0, 0.0, 0.0, RangefinderMount(0), 0.1)
    right_angle = beam_detection(_beam(2.0, fov=math.pi / 2), 0.0, 0.0, 0.0, RangefinderMount(0), 0.1)
    assert wide == right_angle
    assert beam_detection(_beam(None), 0.0, 0.0, 0.0, RangefinderMount(0), 0.1) is None


def test_the_config_fov_stands_in_for_an_unknown_one() -> None:
    told = beam_detection(_beam(4.0), 0.0, 0.0, 0.0, RangefinderMount(0, fov_deg=30.0), 0.1)
    said = beam_detection(_beam(4.0, fov=math.radians(30.0)), 0.0, 0.0, 0.0, RangefinderMount(0), 0.1)
    assert told == said


def test_a_beam_starts_at_its_sensor_and_points_its_way() -> None:
    # The rover at (1, 2) facing north; the sensor 0.3 m forward and 0.1 m left of the reference point
    # (at (0.9, 2.3)), looking right (MAV_SENSOR_ROTATION_YAW_90: east); an echo 2 m away is at (2.9, 2.3).
    found = beam_detection(
        _beam(2.0, bearing=-math.pi / 2), 1.0, 2.0, math.pi / 2, RangefinderMount(0, 0.3, 0.1), 0.1
    )
    assert found is not None
    assert found.points[0] == pytest.approx((2.9, 2.3))
    assert (found.ux, found.uy) == pytest.approx((1.0, 0.0))


def test_an_id_the_config_does_not_place_is_at_the_reference_point_with_one_warning(
    caplog: pytest.LogCaptureFixture,
) -> None:
    placer = BeamPlacer([RangefinderMount(0, 0.5, 0.0)])
    with caplog.at_level(logging.WARNING):
        for _ in range(3):
            (placed, unplaced) = placer.detections(
                [_beam(2.0), _beam(2.0, sensor=7)], 0.0, 0.0, 0.0, min_radius_m=0.1
            )
    assert placed.edge_x == pytest.approx(2.5) and unplaced.edge_x == pytest.approx(2.0)
    assert placer.unmounted == {7}
    assert len([r for r in caplog.records if "rangefinder 7" in r.message]) == 1


def _drive_past_a_rock() -> list[ObstacleObservation]:
    """The default ring on a rover driving at 1 m/s along x past a rock 1.5 m to the side of its line:
    the rock crosses the front, front-left and left cones in turn."""
    tracker = ScanTracker(ScanTrackerConfig(rangefinders=RING))
    reported: list[ObstacleObservation] = []
    for i in range(80):
        pose = (0.1 * i, 0.0, 0.0)
        tracker.add_beams(beams_of([("rock", 6.0, 1.5, 0.6, 0.0, 0.0)], pose, i * READ_NS), pose)
        reported += tracker.poll()
    return reported


def test_a_rock_swept_by_the_cones_of_a_passing_rover_stays_static() -> None:
    # Each beam's disc lies on its axis wherever in the cone the echo came from: as the cones swept the
    # rock its discs slid along with them, and every report of it was moving (29 of 29, before beams were
    # kept from judging motion).
    reported = _drive_past_a_rock()
    assert reported and not any(o.moving for o in reported)
    # Each report's disc touches the rock (to 5 cm) or overlaps it: the near side seen from the rover.
    assert all(math.hypot(o.x - 6.0, o.y - 1.5) < 0.6 + o.radius_m + 0.05 for o in reported)


@pytest.mark.parametrize("step_m", [0.05, 0.1])
def test_a_beam_sweeping_a_wall_maps_it_piece_by_piece_instead_of_dragging_one_track(step_m: float) -> None:
    # The rover drives sideways past a wall 3 m ahead, its front rangefinder (a narrow beam) reading it
    # every 0.1 s, ``step_m`` further along each time. Guidance maps a static obstacle where it is first
    # reported; a track the beam dragged along the wall left the rest of it unmapped (on
    # scenarios/hidden-boulders.toml seed 5 the rover drove into a boulder's front so). A beam continues
    # a track only where their discs overlap, and one that saw a mapped track again holds it where it is:
    # the wall is a row of tracks, each reported where it was first.
    tracker = ScanTracker(ScanTrackerConfig(rangefinders=RING))
    reported: list[ObstacleObservation] = []
    for i in range(round(3.0 / step_m) + 1):
        tracker.add_beams([RangeBeam(i * READ_NS, 0, 0.0, 3.0, 0.2, 7.0, None)], (0.0, step_m * i, 0.0))
        reported += tracker.poll()
    first: dict[str, ObstacleObservation] = {}
    for o in reported:
        first.setdefault(o.obstacle_id, o)
        assert math.hypot(o.x - first[o.obstacle_id].x, o.y - first[o.obstacle_id].y) < 0.1
    mapped_y = sorted(o.y for o in first.values())
    assert len(mapped_y) >= 5 and mapped_y[0] < 0.5 and mapped_y[-1] > 2.5
    assert max(b - a for a, b in itertools.pairwise(mapped_y)) < 0.6


def test_rangefinders_do_not_make_a_slow_lidars_track_look_lost() -> None:
    # A 0.5 Hz lidar sees a rock behind the rover; the ring in front reads every 0.1 s and sees nothing.
    # The tracker remembers tracks for 2.5 periods of its slowest sensor: the lidar's 2 s, not the ring's
    # 0.1 s. (With one period for all, the rock was forgotten before each scan and came back as a new
    # track, never seen three times: nothing was reported.) Its first gap, before the lidar's period is
    # known, forgets scan-1, as with the lidar alone.
    tracker = ScanTracker(ScanTrackerConfig(rangefinders=RING))
    pose = (0.0, 0.0, 0.0)
    rock = [("rock", -4.0, 0.0, 0.5, 0.0, 0.0)]
    reported: list[ObstacleObservation] = []
    for i in range(200):
        t_ns = i * READ_NS
        if i % 20 == 0:
            tracker.add(scan_of(rock, pose, t_ns), pose)
        tracker.add_beams(beams_of(rock, pose, t_ns + 1), pose)
        reported += tracker.poll()
    assert {o.obstacle_id for o in reported} == {"scan-2"} and len(reported) == 7
    assert tracker.track_count == 1 and not any(o.moving for o in reported)
    assert tracker.beam_batches == 200 and tracker.scans == 10


def test_beams_before_a_pose_are_only_counted_and_an_empty_read_is_nothing() -> None:
    tracker = ScanTracker()
    tracker.add_beams([_beam(2.0)], None)
    tracker.add_beams([], (0.0, 0.0, 0.0))
    assert tracker.beams_without_pose == 1 and tracker.beam_batches == 0


def test_the_rangefinders_table_is_read_and_a_bad_entry_named() -> None:
    config = rover_config_from_table(
        parse_toml(
            "[perception]\n"
            "rangefinders = [{id = 0, forward_m = 0.3, left_m = 0.1}, {id = 4, fov_deg = 20.0}]\n",
            "<t>",
        )
    )
    assert config.perception.rangefinders == (
        RangefinderMount(0, 0.3, 0.1),
        RangefinderMount(4, fov_deg=20.0),
    )
    for text, named in [
        ("rangefinders = [{id = 1}, {id = 1}]", r"rangefinders\[1\]\.id"),
        ("rangefinders = [{id = 256}]", r"rangefinders\[0\]\.id"),
        ("rangefinders = [{forward_m = 0.2}]", r"rangefinders\[0\]\.id"),
        ("rangefinders = [{id = 0, left_m = 9.0}]", r"rangefinders\[0\]\.left_m"),
        ("rangefinders = [{id = 0, fov_deg = 120.0}]", r"rangefinders\[0\]\.fov_deg"),
        ("rangefinders = [{id = 0, yaw_deg = 90.0}]", r"rangefinders\[0\]\.yaw_deg"),
    ]:
        with pytest.raises(ConfigError, match=named):
            rover_config_from_table(parse_toml(f"[perception]\n{text}\n", "<t>"))


def test_each_rangefinder_is_watched_on_its_own() -> None:
    events: list[tuple[str, str]] = []
    watch = RangefinderWatch(lambda kind, _severity, detail: events.append((kind, detail)))
    for i in range(10):
        watch.heard(0, i * READ_NS)
        watch.heard(1, i * READ_NS)
    for i in range(10, 30):  # rangefinder 1 falls silent; 0 goes on
        watch.heard(0, i * READ_NS)
        watch.check(i * READ_NS)
    ((kind, detail),) = events
    assert kind == "perception_lost" and "rangefinder 1 " in detail and "every 0.10 s" in detail
    watch.heard(1, 30 * READ_NS)
    assert events[-1][0] == "perception_back" and "rangefinder 1 again" in events[-1][1]
