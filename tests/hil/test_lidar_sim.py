"""The simulated lidar: each ray's range is the nearest obstacle edge along it, within range, seeded noise."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from firmware_bridge.mavlink_transport import memory_pipe_pair
from hil.lidar_sim import SimLidar
from logs.clock import SimClock

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


@pytest.mark.parametrize(
    ("setting", "value"), [("range_m", 0.0), ("rate_hz", 0.0), ("fov_deg", 400.0), ("noise_m", -1.0)]
)
def test_settings_out_of_range_are_refused(setting: str, value: float) -> None:
    settings: dict[str, Any] = {setting: value}
    with pytest.raises(ValueError, match=setting):
        _lidar([], **settings)
