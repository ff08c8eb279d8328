"""Sideways sliding of the body against closed forms: parked and driving across a side slope, level ground.

The rover heads east (yaw 0) across a plane rising to the north (its left), so its roll is the slope angle
and gravity's cross-slope part pulls it to the right (-y, downhill). Test classes have no sinkage, so each
wheel's rolling resistance is exactly ``crr N`` and the closed forms hold to rounding.
"""

import itertools
import math

import numpy as np
import pytest

from hil.dynamics import RoverDynamics
from hil.traction import sideways_grip, sideways_speed
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TERRAIN_CLASSES, TerrainClass
from navigator.vehicle import G, VehicleParams

PARAMS = VehicleParams()
DT = 0.01
VOLTS = 24.0
MU = 0.3  # mud's


def side_slope(degrees: float, size: tuple[int, int] = (80, 80), res: float = 0.25) -> TerrainMap:
    """A plane rising to the north at ``degrees``."""
    ys = (np.arange(size[0]) + 0.5) * res
    elevation = np.broadcast_to(math.tan(math.radians(degrees)) * ys[:, np.newaxis], size).copy()
    return TerrainMap(elevation, np.zeros(size, np.uint8), np.zeros(size, bool), res)


def ground(crr: float) -> dict[int, TerrainClass]:
    return {0: TerrainClass(0, "test", MU, crr, 1.0, "test")}


def ramped(body: RoverDynamics, top_mps: float, seconds: float, ramp_s: float = 2.0) -> list:
    """Drive straight, the wheels ramped to ``top_mps`` over ``ramp_s`` (a gentle start: the pull that
    accelerates the body uses little of the friction)."""
    steps = []
    for i in range(round(seconds / DT)):
        wheel = top_mps * min(1.0, i * DT / ramp_s)
        steps.append(body.step(DT, [wheel] * 6, VOLTS))
    return steps


def test_parked_below_the_holding_slope_it_does_not_slide():
    degrees = 15.0  # tan 0.268 < mu 0.3
    body = RoverDynamics(side_slope(degrees), PARAMS, ground(0.15), x=10.0, y=10.0, yaw=0.0)
    steps = [body.step(DT, [0.0] * 6, VOLTS) for _ in range(200)]
    assert all(s.lateral_speed_mps == 0.0 for s in steps)
    assert body.x == 10.0 and body.y == 10.0
    assert body.roll == pytest.approx(math.radians(degrees))


def test_parked_past_the_holding_slope_it_slides_downhill_at_the_papers_rate():
    """``a = g (sin phi - mu cos phi)`` sideways: the wheels hold nothing along, their whole friction
    circle holds sideways. Tolerance: 1e-9 relative (the same law in floats; only rounding differs)."""
    degrees = 18.0  # tan 0.325 > mu 0.3
    phi = math.radians(degrees)
    body = RoverDynamics(side_slope(degrees), PARAMS, ground(0.15), x=10.0, y=10.0, yaw=0.0)
    steps = [body.step(DT, [0.0] * 6, VOLTS) for _ in range(100)]
    expected = G * (math.sin(phi) - MU * math.cos(phi))
    accel = (steps[-1].lateral_speed_mps - steps[49].lateral_speed_mps) / (50 * DT)
    assert accel == pytest.approx(-expected, rel=1e-9)  # to the right: downhill
    assert body.y < 10.0 and body.x == pytest.approx(10.0, abs=1e-12)
    assert body.speed == 0.0 and body.yaw_rate == 0.0
    # The IMU feels the sliding: specific force y = a_y + g cos(pitch) sin(roll).
    assert steps[-1].specific_force_body_mps2[1] == pytest.approx(G * math.sin(phi) - expected, rel=1e-9)
    assert steps[-1].lateral_accel_mps2 == pytest.approx(-expected, rel=1e-9)


@pytest.mark.parametrize(("crr", "slides"), [(0.15, True), (0.0, False)])
def test_driving_across_a_slope_the_pull_leaves_too_little_friction_sideways(crr, slides):
    """Below the parked holding slope (tan 15.5 deg = 0.277 < mu), driving straight at a steady speed:
    each wheel pulls its rolling resistance ``crr N_i`` and holds sideways ``sqrt((mu N_i)^2 - (crr N_i)^2)``,
    so the body slides at ``g (sin phi - sqrt(mu^2 - crr^2) cos phi)`` when that is positive (crr 0.15:
    sqrt(mu^2 - crr^2) = 0.260 < 0.277) and not at all with no pull to make (crr 0). Tolerance: 1e-6
    relative (the pull settles to ``crr N_i`` within the drive time constant).

    The rover's centre of gravity is on the ground (1 um up), so the start's acceleration loads no axle
    more than another: the slide's friction then makes no yaw moment and the heading stays along the
    contour, where the law holds. (The default rover's 0.30 m loads the rear while it accelerates, so
    sliding its nose swings ~1 deg downhill, ``test_slide_yaw.py``; a degree off the contour the slope's
    pull along the heading changes the wheels' pull, and the slide, a small difference of two ~2.5 m/s^2
    terms, is 0.148 m/s^2 over the last second instead of 0.166.)"""
    degrees = 15.5
    phi = math.radians(degrees)
    low = VehicleParams(cg_height_m=1e-6)
    body = RoverDynamics(side_slope(degrees), low, ground(crr), x=3.0, y=10.0, yaw=0.0)
    steps = ramped(body, 0.5, 5.0)
    if not slides:
        assert all(s.lateral_speed_mps == 0.0 for s in steps)
        assert body.y == pytest.approx(10.0, abs=1e-6)
        return
    expected = G * (math.sin(phi) - math.sqrt(MU**2 - crr**2) * math.cos(phi))
    assert expected > 0.0
    accel = (steps[-1].lateral_speed_mps - steps[399].lateral_speed_mps) / (100 * DT)
    assert accel == pytest.approx(-expected, rel=1e-6)
    last = steps[-1]
    grip = sideways_grip(
        np.array(last.normal_forces_n), np.array(last.traction_forces_n), MU, np.zeros(6), 0.0, 0.0, 1.0, 0.0
    )
    assert grip == pytest.approx(math.sqrt(MU**2 - crr**2) * sum(last.normal_forces_n), rel=1e-6)
    assert body.y < 10.0 - 0.3  # it drifted downhill while driving along the contour
    assert body.yaw == pytest.approx(0.0, abs=1e-3)


def test_sliding_stops_once_the_friction_holds_again_and_never_reverses():
    """Coulomb friction: a body sliding on a slope it can hold on decelerates at the friction's excess
    and comes to rest at exactly 0; it never slides back uphill."""
    degrees = 14.0  # holds parked and driving (tan 0.249 < sqrt(mu^2 - crr^2) 0.260)
    body = RoverDynamics(side_slope(degrees), PARAMS, ground(0.15), x=3.0, y=10.0, yaw=0.0)
    # An abrupt start: accelerating to 0.5 m/s within the drive time constant spends the friction on the
    # pull, and the body slides while it accelerates.
    steps = [body.step(DT, [0.5] * 6, VOLTS) for _ in range(1000)]
    lateral = [s.lateral_speed_mps for s in steps]
    assert min(lateral) < -0.05
    assert all(v <= 0.0 for v in lateral)
    assert lateral[-1] == 0.0


def test_past_the_tip_angle_on_firm_ground_it_slides_before_it_tips():
    """mu 0.8 < (track / 2) / h_cg = 0.917: parked across a 45 deg slope (past the 42.5 deg tip angle) the
    friction cannot hold the body, so it slides, and a sliding body's tipping load is the friction's: its
    specific force's tilt ``atan(f_y / f_z)`` = ``atan(mu)`` stays below the tip angle."""
    body = RoverDynamics(side_slope(45.0), PARAMS, x=10.0, y=10.0, yaw=0.0)
    steps = [body.step(DT, [0.0] * 6, VOLTS) for _ in range(50)]
    assert not any(s.rollover for s in steps[1:])
    assert steps[-1].lateral_speed_mps < -0.5 and steps[-1].roll_margin_rad > 0.0
    firm = TERRAIN_CLASSES[0].friction_mu
    slide = G * (math.sin(math.pi / 4.0) - firm * math.cos(math.pi / 4.0))
    assert steps[-1].lateral_accel_mps2 == pytest.approx(-slide, rel=1e-9)


def test_a_sliding_bodys_margin_is_the_tilt_of_its_specific_force():
    """Parked across 51 deg on firm ground (mu 0.8) it slides; the friction's pull leaves the specific
    force at ``f_y / f_z = mu``, so the roll margin is ``tip_roll - atan(mu)`` = 3.85 deg, the wheel loads'
    (not ``roll + atan(a_y / g)``'s 6.8 deg)."""
    body = RoverDynamics(side_slope(51.0), PARAMS, x=10.0, y=12.0, yaw=0.0)
    steps = [body.step(DT, [0.0] * 6, VOLTS) for _ in range(30)]
    assert not any(s.rollover for s in steps)
    firm = TERRAIN_CLASSES[0].friction_mu
    _, f_y, f_z = steps[-1].specific_force_body_mps2
    assert f_y / f_z == pytest.approx(firm, rel=1e-9)
    expected = PARAMS.tip_roll_rad - math.atan(firm)
    assert steps[-1].roll_margin_rad == pytest.approx(expected, rel=1e-9)
    assert math.degrees(expected) == pytest.approx(3.85, abs=0.01)


def test_locked_wheels_sliding_down_a_slope_resist_sideways_as_a_sliding_block():
    """Parked (wheels locked) 60 deg off the contour of a 25 deg plane, mu 0.3: gravity along the heading
    is past the wheels' grip, so they slide along at ``mu N``; their friction then follows their sliding
    velocity, not what the circle leaves after ``mu N`` (nothing, as on ice: before, the body slid away
    sideways at 2.9 m/s after 1.5 s). Like a block, it slides down the fall line (its track within 6 % of
    straight downhill) no faster than ``g (sin phi - mu cos phi)`` (friction at least ``mu N``: more while
    its velocity is oblique to a wheel, see ``sideways_grip``'s limits) and not much slower: 0.78 of it.

    Its heading stays within 2 deg of where it started: the slide's yaw moment (nose down, the front axle
    loaded, its rear swings downhill) balances the sides' unequal braking (the downhill side loaded), which
    alone turned it 21 deg towards the fall line in 1.5 s. So it slides 30 deg off its heading, its
    sideways speed is half its speed (0.9 m/s; 2.9 on ice), and the oblique friction's excess slows it
    (before the moment, turned nearly downhill, it reached 0.87 of the block's speed, 2 % off the line)."""
    degrees = 25.0
    phi = math.radians(degrees)
    body = RoverDynamics(
        side_slope(degrees, (160, 160)), PARAMS, ground(0.15), x=20.0, y=25.0, yaw=-math.pi / 3
    )
    steps = [body.step(DT, [0.0] * 6, VOLTS) for _ in range(150)]
    last = steps[-1]
    pulls, loads = np.array(last.traction_forces_n), np.array(last.normal_forces_n)
    assert np.abs(pulls) == pytest.approx(MU * loads)  # every wheel at its limit: sliding
    moved_x, moved_y = body.x - 20.0, body.y - 25.0
    assert moved_y < -1.0 and abs(moved_x) < 0.06 * abs(moved_y)
    speed = math.hypot(last.speed_mps, last.lateral_speed_mps)
    block = G * (math.sin(phi) - MU * math.cos(phi)) * 150 * DT
    assert 0.75 * block < speed <= block
    assert body.yaw == pytest.approx(-math.pi / 3, abs=math.radians(2.0))
    assert abs(last.lateral_speed_mps) == pytest.approx(0.5 * speed, rel=0.05)


def test_the_friction_circle_and_the_coulomb_step():
    normals = np.array([50.0, 60.0, 70.0, 40.0, 50.0, 60.0])

    def grip(
        forces: np.ndarray, wheels: np.ndarray | None = None, speed: float = 0.0, lateral: float = 0.0
    ) -> float:
        wheels = np.full(6, speed) if wheels is None else wheels
        return sideways_grip(normals, forces, 0.5, wheels, speed, 0.0, 0.9, lateral)

    assert grip(np.zeros(6)) == pytest.approx(0.5 * normals.sum())
    pulls = 0.3 * normals
    assert grip(pulls) == pytest.approx(0.4 * normals.sum())  # 3-4-5
    # Spinning at mu N (surface 2 m/s over ground at rest), not sliding sideways: nothing (share 0)...
    spinning = np.full(6, 2.0)
    assert grip(0.5 * normals, spinning) == 0.0
    # ... sliding sideways at 2 m/s too: the sideways part of the sliding velocity, 45 deg.
    share = 2.0 / math.hypot(2.0, 2.0)
    assert grip(0.5 * normals, spinning, lateral=-2.0) == pytest.approx(0.5 * normals.sum() * share)
    # Locked (surface 0) while the body slides along at 0.1 m/s and sideways at 3 m/s: nearly mu N.
    locked = grip(-0.5 * normals, np.zeros(6), speed=0.1, lateral=3.0)
    assert locked == pytest.approx(0.5 * normals.sum() * 3.0 / math.hypot(3.0, 0.1))
    # Below the limit and sliding sideways: the larger of the circle's rest and |F| share, so no jump at
    # the limit. Pulling 0.8 mu N, not sliding along: 0.8 mu N (the circle leaves 0.6); 0.3 mu N: the
    # circle's 0.95 mu N; 0.999999 mu N: the Coulomb part, ~ what the limit gives.
    rolling = np.zeros(6)
    assert grip(0.4 * normals, rolling, lateral=-0.2) == pytest.approx(0.4 * normals.sum())
    circle = math.sqrt(0.5**2 - 0.15**2) * normals.sum()
    assert grip(0.15 * normals, rolling, lateral=-0.2) == pytest.approx(circle)
    near, at = grip(0.4999995 * normals, spinning, lateral=-2.0), grip(0.5 * normals, spinning, lateral=-2.0)
    assert near == pytest.approx(at, rel=1e-5)
    lifted = normals.copy()
    lifted[:3] = 0.0
    assert sideways_grip(lifted, np.zeros(6), 0.5, np.zeros(6), 0.0, 0.0, 0.9, 1.0) == pytest.approx(
        0.5 * lifted.sum()
    )
    assert sideways_speed(0.0, -2.0, 2.5, DT) == 0.0  # within the grip: held exactly
    assert sideways_speed(0.0, -3.0, 2.5, DT) == pytest.approx(-0.5 * DT)
    assert sideways_speed(-0.001, 0.0, 2.5, DT) == 0.0  # stopped, not reversed
    assert sideways_speed(-0.1, 0.0, 2.5, DT) == pytest.approx(-0.1 + 2.5 * DT)


@pytest.mark.parametrize("class_id", sorted(TERRAIN_CLASSES))
def test_on_the_level_the_body_never_slides_at_the_rovers_speeds(class_id):
    """Straight at top speed, a turn on the spot, and an arc at the follower's lateral limit (1 m/s^2 at
    1 m/s, far below any class's sideways grip) entered from a straight run: the sideways speed stays
    exactly 0.0, so every state is the one the model gave before sliding existed.

    (An arc commanded from rest on mud is not in the list: its wheels spin at full traction while the body
    picks up speed, which leaves them little sideways grip, and it slides by under 1 mm/s: as it should.)"""
    size = (160, 160)
    flat = TerrainMap(np.zeros(size), np.full(size, class_id, np.uint8), np.zeros(size, bool), 0.25)
    top = PARAMS.max_wheel_speed_mps
    difference = 1.0 * PARAMS.effective_track_m  # w = 1 rad/s at 1 m/s
    arc = [1.0 - difference / 2.0] * 3 + [1.0 + difference / 2.0] * 3
    runs = (
        [[top] * 6] * 300,
        [[-top] * 3 + [top] * 3] * 300,
        [[1.0] * 6] * 200 + [arc] * 300,
    )
    for commands in runs:
        body = RoverDynamics(flat, PARAMS, x=20.0, y=20.0, yaw=0.0)
        steps = [body.step(DT, wheels, VOLTS) for wheels in commands]
        assert all(s.lateral_speed_mps == 0.0 for s in steps)
        assert abs(body.yaw_rate) > 0.3 or commands[-1][0] == top  # it turned (or ran straight)


def test_a_locked_rovers_slide_changes_continuously_with_its_heading():
    """Parked (wheels locked) on a plane of grade 0.35 (19.3 deg, mu 0.3: a block slides 0.874 m down the
    fall line in 2 s), headings 0..90 deg off the contour, 1 deg apart. Before, a wheel's sideways grip
    jumped from the circle's ~0 just below its limit to ``mu N share`` at it, and the drop jumped with the
    heading (1.03 m at 30 deg, 0.07 m at 45, 0.23 m at 56, 0.025 m at 58). Now: no two neighbours differ
    by more than 0.1 m; along the contour (no pull) and straight downhill (every wheel sliding along at its
    limit) it drops as a block (1 %); never more than 20 % past a block (the circle's rest, less than
    ``mu N``, while the wheels hold along). In between it drops less than a block: see ``sideways_grip``'s
    limits.

    Since the slide's friction turns the body (``slide_yaw_moment``), up to 1.18 times a block's at 11-12
    deg (1.11 at 24 deg before; two humps, 12 and 21 deg): turned by the moment, its yaw rate changes sign
    every few steps and the locked wheels' hold along hops from one side to the other (a wheel whose slip
    opposes its side's force holds nothing, ``_wheel_caps``), which leaves less of the circles sideways."""
    phi = math.atan(0.35)
    plane = side_slope(math.degrees(phi), (200, 200))
    block = 0.5 * G * (math.sin(phi) - MU * math.cos(phi)) * 2.0**2 * math.cos(phi)  # horizontal
    drops = []
    for off in range(91):
        body = RoverDynamics(plane, PARAMS, ground(0.15), x=25.0, y=30.0, yaw=-math.radians(off))
        for _ in range(200):
            step = body.step(DT, [0.0] * 6, VOLTS)
        drops.append(30.0 - body.y)
        if off >= 75:
            pulls, loads = np.abs(step.traction_forces_n), np.array(step.normal_forces_n)
            assert pulls == pytest.approx(MU * loads)  # every wheel sliding along at its limit
    assert block == pytest.approx(0.874, abs=1e-3)
    assert max(abs(b - a) for a, b in itertools.pairwise(drops)) < 0.1
    assert drops[0] == pytest.approx(block, rel=0.01) and drops[90] == pytest.approx(block, rel=0.01)
    assert max(drops) < 1.2 * block
    assert drops[75:] == sorted(drops[75:])  # towards the block's as the wheels slide more along
