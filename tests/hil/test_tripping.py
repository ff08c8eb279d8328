"""A sideways slide stopped by an obstacle: tripped over (or not) by the critical sliding speed, whatever dt.

Parked (wheels locked) on a 20 deg side slope rising to the north on a slippery class (mu 0.1), the rover
slides downhill (south, its right) at ``a = g (sin phi - mu cos phi)`` into a row of obstacle cells placed
so that it arrives at a chosen speed: well below and well above ``critical_sliding_speed``.
"""

import math

import numpy as np
import pytest

from hil.dynamics import RoverDynamics
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TerrainClass
from navigator.vehicle import G, VehicleParams, critical_sliding_speed

PARAMS = VehicleParams()
VOLTS = 24.0
SLOPE_DEG = 20.0
MU = 0.1
RES = 0.25
WALL_ROW = 30  # the obstacle row; its top (north) edge is at y = 31 * RES


def slope_with_wall(degrees: float = SLOPE_DEG, size: tuple[int, int] = (80, 80)) -> TerrainMap:
    ys = (np.arange(size[0]) + 0.5) * RES
    elevation = np.broadcast_to(math.tan(math.radians(degrees)) * ys[:, np.newaxis], size).copy()
    obstacles = np.zeros(size, bool)
    obstacles[WALL_ROW, :] = True
    return TerrainMap(elevation, np.zeros(size, np.uint8), obstacles, RES)


def slide_into_the_wall(
    gap_m: float, dt: float, degrees: float = SLOPE_DEG, mu: float = MU, seconds: float = 3.0
) -> tuple[float, bool]:
    """Slide from rest ``gap_m`` above the wall until the wall stops it or it rolls over: (the sideways
    speed the step before, rolled over)."""
    classes = {0: TerrainClass(0, "slippery", mu, 0.0, 1.0, "test")}
    y = (WALL_ROW + 1) * RES + 0.5 * PARAMS.footprint_width_m + gap_m
    body = RoverDynamics(slope_with_wall(degrees), PARAMS, classes, x=10.0, y=y, yaw=0.0)
    before = 0.0
    for _ in range(round(seconds / dt)):
        step = body.step(dt, [0.0] * 6, VOLTS)
        if step.rollover or (step.collided and step.lateral_speed_mps == 0.0):
            return before, step.rollover
        before = step.lateral_speed_mps
    raise AssertionError("it never reached the wall")


def critical() -> float:
    return critical_sliding_speed(PARAMS.track_m, PARAMS.cg_height_m, PARAMS.tip_roll_rad - math.radians(20))


def test_the_critical_sliding_speed_is_chrstos_and_guenthers():
    """On the level, CSV = sqrt(2 g I_edge (sqrt(T^2/4 + h^2) - h) / (m h^2)) with I_edge = m R^2."""
    track, h = PARAMS.track_m, PARAMS.cg_height_m
    lever_sq = (track / 2.0) ** 2 + h**2
    csv = math.sqrt(2.0 * G * lever_sq * (math.sqrt(lever_sq) - h) / h**2)
    assert critical_sliding_speed(track, h, PARAMS.tip_roll_rad) == pytest.approx(csv, rel=1e-12)
    assert critical_sliding_speed(track, h, 0.0) == 0.0  # no margin left: any stop tips it
    assert critical_sliding_speed(track, h, 0.2) < critical_sliding_speed(track, h, 0.3)
    assert critical() == pytest.approx(1.058, abs=1e-3)


@pytest.mark.parametrize("dt", [0.005, 0.01, 0.02])
@pytest.mark.parametrize(("share", "trips"), [(0.7, False), (1.4, True)])
def test_a_slide_into_an_obstacle_trips_past_the_critical_speed_whatever_dt(dt, share, trips):
    """The gap that ``a = g (sin phi - mu cos phi)`` takes to reach ``share`` of the critical speed."""
    phi = math.radians(SLOPE_DEG)
    accel = G * (math.sin(phi) - MU * math.cos(phi))
    gap = (share * critical()) ** 2 / (2.0 * accel)
    speed, rolled = slide_into_the_wall(gap, dt)
    assert -speed == pytest.approx(share * critical(), rel=0.1)  # it arrived as planned
    assert rolled == trips


@pytest.mark.parametrize("dt", [0.005, 0.01, 0.02])
def test_a_slow_slide_stopped_by_an_obstacle_is_not_a_rollover(dt):
    """The reviewer's case: mud-like mu 0.3 across 16.8 deg, just past its holding slope, creeping into
    the wall at ~8 cm/s (before, the stop counted as an acceleration v / dt and tipped the margin at dt
    0.01 and 0.005, not at 0.02)."""
    speed, rolled = slide_into_the_wall(0.18, dt, degrees=16.8, mu=0.3, seconds=8.0)
    assert -speed == pytest.approx(0.08, abs=0.01)
    assert not rolled


@pytest.mark.parametrize("dt", [0.005, 0.01, 0.02])
def test_a_head_on_stop_at_an_obstacle_is_not_a_pitch_over(dt):
    """Driving at top speed into a wall on the level: the stop is an impact, not a deceleration of
    ``v / dt`` (which would tilt the specific force past the 49 deg pitch tip angle at any of these dt)."""
    size = (80, 80)
    obstacles = np.zeros(size, bool)
    obstacles[:, 60] = True  # a wall at x = 15 m
    flat = TerrainMap(np.zeros(size), np.zeros(size, np.uint8), obstacles, RES)
    body = RoverDynamics(flat, PARAMS, x=5.0, y=10.0, yaw=0.0)
    top = PARAMS.max_wheel_speed_mps
    fastest = 0.0
    for _ in range(round(12.0 / dt)):
        step = body.step(dt, [top] * 6, VOLTS)
        assert not step.rollover
        if step.collided and step.speed_mps == 0.0:
            break
        fastest = max(fastest, step.speed_mps)
    else:
        raise AssertionError("it never reached the wall")
    assert fastest > 1.4
