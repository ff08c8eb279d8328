"""The simulated lidar: each ray's range is the nearest obstacle edge along it, within range, seeded noise."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from firmware_bridge.mavlink_transport import memory_pipe_pair
from hil.lidar_sim import SimLidar
from logs.clock import SimClock
from navigator.sensor_mount import SensorMount

ROCK = ("rock", 4.0, 0.0, 0.5, 0.0, 0.0)


def _lidar(discs: list, *, noise_m: float = 0.0, seed: int = 0, **kwargs: Any) -> SimLidar:
    return SimLidar(
        memory_pipe_pair()[0],
        SimClock(0),
        lambda _t: discs,
        np.random.default_rng(seed),
        noise_m=noise_m,
        **kwargs,
    )


def test_the_ray_at_a_disc_reads_its_near_edge_and_the_others_nothing() -> None:
    ranges = _lidar([ROCK]).ranges(0, 0.0, 0.0, 0.0)
    assert ranges[0] == pytest.approx(3.5)  # sector 0: straight ahead
    hits = [i for i, r in enumerate(ranges) if r is not None]
    assert set(hits) <= {70, 71, 0, 1, 2}  # only the sectors around the front
    # Turned a quarter to the left, the rock lies to the right: 18 sectors clockwise from the front.
    turned = _lidar([ROCK]).ranges(0, 0.0, 0.0, math.pi / 2)
    assert turned[18] == pytest.approx(3.5) and turned[0] is None


def test_past_its_range_or_behind_a_nearer_one_it_sees_the_nearest_only() -> None:
    assert all(r is None for r in _lidar([("far", 9.0, 0.0, 0.5, 0.0, 0.0)]).ranges(0, 0.0, 0.0, 0.0))
    near_and_far = _lidar([ROCK, ("behind", 7.0, 0.0, 0.5, 0.0, 0.0)]).ranges(0, 0.0, 0.0, 0.0)
    assert near_and_far[0] == pytest.approx(3.5)


def test_the_noise_is_the_seeds_and_the_field_of_view_is_centred_on_the_front() -> None:
    a = _lidar([ROCK], noise_m=0.05, seed=3).ranges(0, 0.0, 0.0, 0.0)
    b = _lidar([ROCK], noise_m=0.05, seed=3).ranges(0, 0.0, 0.0, 0.0)
    assert a == b and a[0] != pytest.approx(3.5, abs=1e-6)
    narrow = _lidar([ROCK], fov_deg=180.0)
    assert narrow.increment_deg == 2.5 and narrow.angle_offset_deg == pytest.approx(-88.75)


def test_a_mounted_lidar_casts_from_where_it_sits_and_counts_from_its_own_front() -> None:
    # 0.4 m forward: the rock's near edge 3.5 m from the rover's centre is 3.1 m from the sensor.
    assert _lidar([ROCK], mount=SensorMount(forward_m=0.4)).ranges(0, 0.0, 0.0, 0.0)[0] == pytest.approx(3.1)
    # 0.5 m forward and turned to the left: the sensor at (0.5, 0) faces north. A rock 4 m north of it is
    # straight ahead of the sensor (sector 0); the one ahead of the rover is 3.5 m to the sensor's right,
    # 90 deg clockwise (sector 18), its near edge 3 m away.
    turned = SensorMount(forward_m=0.5, yaw_rad=math.pi / 2)
    left = ("left", 0.5, 4.0, 0.5, 0.0, 0.0)
    ranges = _lidar([ROCK, left], mount=turned).ranges(0, 0.0, 0.0, 0.0)
    assert ranges[0] == pytest.approx(3.5) and ranges[18] == pytest.approx(3.0)
    # The same rover facing north (yaw 90 deg) at (1, 2): the sensor at (1, 2.5) faces west.
    west = ("west", -3.0, 2.5, 0.5, 0.0, 0.0)
    assert _lidar([west], mount=turned).ranges(0, 1.0, 2.0, math.pi / 2)[0] == pytest.approx(3.5)
    # A narrow view is centred on the sensor's front: the rock on the left, not the one ahead of the rover.
    narrow = _lidar([ROCK, left], mount=turned, fov_deg=90.0).ranges(0, 0.0, 0.0, 0.0)
    seen = [r for r in narrow if r is not None]
    assert seen and min(seen) == pytest.approx(3.5, abs=0.05)  # 3.0 would be the rock ahead of the rover


@pytest.mark.parametrize(
    ("setting", "value"),
    [
        ("range_m", 0.0),
        ("rate_hz", 0.0),
        ("fov_deg", 400.0),
        ("noise_m", -1.0),
        ("mount", SensorMount(forward_m=math.nan)),
    ],
)
def test_settings_out_of_range_are_refused(setting: str, value: float) -> None:
    settings: dict[str, Any] = {setting: value}
    with pytest.raises(ValueError, match=setting):
        _lidar([], **settings)
