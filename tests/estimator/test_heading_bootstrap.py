import math

import pytest

from estimator.heading_bootstrap import HeadingBootstrap


def _drive(boot: HeadingBootstrap, yaw0: float, speed: float, rate: float, seconds: float) -> tuple:
    """Exact kinematics from (0, 0) at yaw0, fed as 10 ms steps; returns the final (x, y, yaw)."""
    x = y = 0.0
    yaw = yaw0
    dt = 0.01
    for _ in range(round(seconds / dt)):
        mid = yaw + 0.5 * rate * dt
        x += speed * dt * math.cos(mid)
        y += speed * dt * math.sin(mid)
        yaw += rate * dt
        boot.add_motion(rate * dt, speed * dt)
    return x, y, yaw


@pytest.mark.parametrize(
    ("yaw0", "speed", "rate"),
    [(0.3, 1.0, 0.0), (2.5, 0.8, 0.3), (-2.0, -0.6, 0.2), (3.1, 0.7, -0.25)],
)
def test_heading_from_dead_reckoning_and_gps(yaw0, speed, rate):
    boot = HeadingBootstrap(min_distance_m=5.0)
    assert boot.on_fix(0.0, 0.0, 0.5, path_known=True) is None
    x, y, yaw = _drive(boot, yaw0, speed, rate, 10.0)
    guess = boot.on_fix(x, y, 0.5, path_known=True)
    assert guess is not None
    assert math.remainder(guess.yaw_rad - yaw, 2 * math.pi) == pytest.approx(0.0, abs=1e-3)
    assert 0.0 < guess.std_rad < 0.3


def test_no_guess_before_the_distance():
    boot = HeadingBootstrap(min_distance_m=5.0)
    boot.on_fix(0.0, 0.0, 0.5, path_known=True)
    x, y, _ = _drive(boot, 1.0, 1.0, 0.0, 3.0)
    assert boot.on_fix(x, y, 0.5, path_known=True) is None


def test_gps_moving_while_wheels_stand_still_gives_no_guess():
    boot = HeadingBootstrap(min_distance_m=5.0)
    boot.on_fix(0.0, 0.0, 0.5, path_known=True)
    _drive(boot, 0.0, 0.0, 0.0, 5.0)
    assert boot.on_fix(6.0, 0.0, 0.5, path_known=True) is None


def test_without_odometry_assumes_forward_arc():
    boot = HeadingBootstrap(min_distance_m=5.0)
    boot.on_fix(0.0, 0.0, 0.5, path_known=False)
    x, y, yaw = 0.0, 0.0, 1.0
    # feed only the turn, as a filter without odometry would
    for _ in range(1000):
        mid = yaw + 0.5 * 0.002
        x += 0.008 * math.cos(mid)
        y += 0.008 * math.sin(mid)
        yaw += 0.002
        boot.add_motion(0.002, 0.0)
    guess = boot.on_fix(x, y, 0.5, path_known=False)
    assert guess is not None
    assert guess.yaw_rad == pytest.approx(yaw, abs=1e-3)
