"""``estimator.stuck.StuckDetector``: wheels spinning in place are told from a rover driving a curve."""

from __future__ import annotations

import math

import numpy as np

from estimator.stuck import StuckDetector

S = 1_000_000_000


def _run(speed_mps: float, yaw_rate_rps: float, ground_share: float, seconds: float = 8.0) -> bool:
    """Odometry at 50 Hz, GPS at 5 Hz (0.3 m noise); the ground moves ``ground_share`` of what the wheels
    roll, along the same heading. Whether the detector ended up declaring the wheels spinning."""
    rng = np.random.default_rng(4)
    detector = StuckDetector(window_s=4.0, min_distance_m=1.0)
    x = y = yaw = 0.0
    spinning = False
    for k in range(1, round(seconds * 50) + 1):
        t = k * S // 50
        rolled = speed_mps / 50
        yaw += yaw_rate_rps / 50
        detector.add_odometry(t, rolled, yaw)
        x += ground_share * rolled * math.cos(yaw)
        y += ground_share * rolled * math.sin(yaw)
        if k % 10 == 0:
            noise = rng.normal(0.0, 0.3, 2)
            spinning = detector.on_fix(t, x + noise[0], y + noise[1], 0.3)
    return spinning


def test_a_tight_circle_with_full_grip_is_not_spinning() -> None:
    # 0.8 m/s round a 0.6 m radius: the window's GPS chord is short, but so is the odometry's own track.
    assert not _run(0.8, 0.8 / 0.6, ground_share=1.0)


def test_wheels_turning_while_the_rover_stands_still_are_spinning() -> None:
    assert _run(1.0, 0.0, ground_share=0.0)
    assert _run(0.8, 0.8 / 0.6, ground_share=0.0)  # on a curve as well


def test_partial_slip_is_left_to_the_odometry_scale() -> None:
    assert not _run(1.0, 0.0, ground_share=0.8)


def test_the_track_at_the_fixes_times_is_the_walk_per_time():
    """``_track_at`` walks the odometry once for all the fixes' times (in time order); each position must
    be the sum of every step up to its time, added in order: the same floats as walking the steps afresh
    for each time. Times before the first step, on a step, repeated and after the last one included."""
    rng = np.random.default_rng(9)
    detector = StuckDetector(window_s=4.0, min_distance_m=1.0)
    for t in sorted(rng.choice(10_000, size=300, replace=False).tolist()):
        detector.add_odometry(t, float(rng.normal(0.02, 0.01)), float(rng.uniform(-math.pi, math.pi)))
    steps = list(
        zip(detector._step_t, detector._step_rolled, detector._step_east, detector._step_north, strict=True)
    )
    times = sorted([-5, 0, steps[7][0], steps[7][0], 12_000, *rng.integers(0, 10_000, size=40).tolist()])

    def walked(t: int) -> tuple[int, float, float, float]:
        east = north = 0.0
        for step_t, _, step_east, step_north in steps:
            if step_t > t:
                break
            east, north = east + step_east, north + step_north
        return (t, east, north, 0.0)

    assert detector._track_at(times) == [walked(t) for t in times]
