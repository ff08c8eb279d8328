"""A slide stopped by an obstacle: tripped over (or not) by the critical sliding speed, whatever dt, about the
edge it moved towards on each axis.

Parked (wheels locked) on a 20 deg slope on a slippery class (mu 0.1), the rover slides downhill at
``a = g (sin phi - mu cos phi)`` into a row of obstacle cells placed so that it arrives at a chosen speed:
well below and well above ``critical_sliding_speed``. Across the slope (heading east) it slides sideways and
trips over the side it slid towards (the slope rising to the north, or mirrored, to the south); along it
(heading downhill, or uphill and sliding backwards) it pitches over the end axle it slid towards.
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
SIZE = (80, 80)
WALL_ROW = 30  # the obstacle row below a slope rising north; its top (north) edge is at y = 31 * RES
MIRRORED_WALL_ROW = SIZE[0] - 1 - WALL_ROW  # above a slope rising south; its bottom edge at y = 49 * RES


def slope_with_wall(degrees: float = SLOPE_DEG, rising_north: bool = True) -> TerrainMap:
    ys = (np.arange(SIZE[0]) + 0.5) * RES
    rise = ys if rising_north else SIZE[0] * RES - ys
    elevation = np.broadcast_to(math.tan(math.radians(degrees)) * rise[:, np.newaxis], SIZE).copy()
    obstacles = np.zeros(SIZE, bool)
    obstacles[WALL_ROW if rising_north else MIRRORED_WALL_ROW, :] = True
    return TerrainMap(elevation, np.zeros(SIZE, np.uint8), obstacles, RES)


def slide_into_the_wall(
    gap_m: float,
    dt: float,
    degrees: float = SLOPE_DEG,
    mu: float = MU,
    seconds: float = 3.0,
    rising_north: bool = True,
    yaw: float = 0.0,
) -> tuple[float, bool]:
    """Slide from rest ``gap_m`` uphill of the wall until the wall stops it or it rolls over: (its speed over
    the ground the step before, rolled over). ``yaw`` 0 (across the slope) or +-pi/2 (along it)."""
    classes = {0: TerrainClass(0, "slippery", mu, 0.0, 1.0, "test")}
    half = 0.5 * (PARAMS.footprint_width_m if yaw == 0.0 else PARAMS.footprint_length_m)
    wall_edge = (WALL_ROW + 1) * RES if rising_north else MIRRORED_WALL_ROW * RES
    y = wall_edge + (half + gap_m if rising_north else -(half + gap_m))
    body = RoverDynamics(slope_with_wall(degrees, rising_north), PARAMS, classes, x=10.0, y=y, yaw=yaw)
    before = 0.0
    for _ in range(round(seconds / dt)):
        step = body.step(dt, [0.0] * 6, VOLTS)
        moving = math.hypot(step.speed_mps, step.lateral_speed_mps)
        if step.rollover or (step.collided and moving == 0.0):
            return before, step.rollover
        before = moving
    raise AssertionError("it never reached the wall")


def critical() -> float:
    return critical_sliding_speed(PARAMS.track_m, PARAMS.cg_height_m, PARAMS.tip_roll_rad - math.radians(20))


def critical_pitch() -> float:
    """The same law about the end axle: the wheelbase for the track, the pitch margin towards the slide."""
    return critical_sliding_speed(
        PARAMS.wheelbase_m, PARAMS.cg_height_m, PARAMS.tip_pitch_rad - math.radians(SLOPE_DEG)
    )


def test_the_critical_sliding_speed_is_chrstos_and_guenthers():
    """On the level, CSV = sqrt(2 g I_edge (sqrt(T^2/4 + h^2) - h) / (m h^2)) with I_edge = m R^2."""
    track, h = PARAMS.track_m, PARAMS.cg_height_m
    lever_sq = (track / 2.0) ** 2 + h**2
    csv = math.sqrt(2.0 * G * lever_sq * (math.sqrt(lever_sq) - h) / h**2)
    assert critical_sliding_speed(track, h, PARAMS.tip_roll_rad) == pytest.approx(csv, rel=1e-12)
    assert critical_sliding_speed(track, h, 0.0) == 0.0  # no margin left: any stop tips it
    assert critical_sliding_speed(track, h, 0.2) < critical_sliding_speed(track, h, 0.3)
    assert critical() == pytest.approx(1.058, abs=1e-3)


GAP_CASES = [(0.7, False), (1.4, True)]


def gap_for(speed: float) -> float:
    """The gap that ``a = g (sin phi - mu cos phi)`` takes to reach ``speed`` from rest."""
    phi = math.radians(SLOPE_DEG)
    return speed**2 / (2.0 * G * (math.sin(phi) - MU * math.cos(phi)))


@pytest.mark.parametrize("dt", [0.005, 0.01, 0.02])
@pytest.mark.parametrize(("share", "trips"), GAP_CASES)
@pytest.mark.parametrize("rising_north", [True, False])
def test_a_slide_into_an_obstacle_trips_past_the_critical_speed_whatever_dt(dt, share, trips, rising_north):
    """Sideways, to the right (slope rising north) or to the left (mirrored): the margin is the tip angle
    less the tilt towards the side it slid to, 20 deg either way (taking the roll's sign the wrong way on
    either side leaves 62.5 deg of margin, and 1.4 times the critical speed would not trip it)."""
    speed, rolled = slide_into_the_wall(gap_for(share * critical()), dt, rising_north=rising_north)
    assert speed == pytest.approx(share * critical(), rel=0.1)  # it arrived as planned
    assert rolled == trips


@pytest.mark.parametrize("dt", [0.005, 0.01, 0.02])
@pytest.mark.parametrize(("share", "trips"), GAP_CASES)
@pytest.mark.parametrize("yaw", [-math.pi / 2.0, math.pi / 2.0])
def test_a_slide_along_into_an_obstacle_pitches_over_past_its_critical_speed(dt, share, trips, yaw):
    """Heading downhill (nose down, sliding forwards) or uphill (nose up, sliding backwards) into the wall:
    the pitch-over trip about the end axle it slid towards, ``critical_sliding_speed(wheelbase, h, tip_pitch
    - 20 deg)`` = 1.66 m/s (the pitch's sign taken the wrong way leaves 69.4 deg of margin: 3.7 m/s)."""
    assert critical_pitch() == pytest.approx(1.66, abs=0.01)
    speed, rolled = slide_into_the_wall(gap_for(share * critical_pitch()), dt, yaw=yaw)
    assert speed == pytest.approx(share * critical_pitch(), rel=0.1)
    assert rolled == trips


@pytest.mark.parametrize("dt", [0.005, 0.01, 0.02])
def test_a_slow_slide_stopped_by_an_obstacle_is_not_a_rollover(dt):
    """The reviewer's case: mud-like mu 0.3 across 16.8 deg, just past its holding slope, creeping into
    the wall at ~8 cm/s (before, the stop counted as an acceleration v / dt and tipped the margin at dt
    0.01 and 0.005, not at 0.02)."""
    speed, rolled = slide_into_the_wall(0.18, dt, degrees=16.8, mu=0.3, seconds=8.0)
    assert speed == pytest.approx(0.08, abs=0.01)
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
