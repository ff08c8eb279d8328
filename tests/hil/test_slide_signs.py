"""The sliding body's signs, away from the yaw 0, pitch 0 of the closed-form tests: the energy balance of a
slide down a slope taken diagonally, the outward slide of a turn past the grip, and a body coasting on ice
keeping its velocity over the ground while it spins (the body-axes terms ``v_y w`` and ``- v_x w``)."""

import math

import numpy as np
import pytest

from hil.dynamics import RoverDynamics
from hil.traction import sideways_grip
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TerrainClass
from navigator.vehicle import G, VehicleParams

PARAMS = VehicleParams()
DT = 0.01
VOLTS = 24.0
RES = 0.25


def ground_class(mu: float, lateral_resistance: float = 0.4) -> TerrainClass:
    return TerrainClass(0, "test", mu, 0.0, 1.0, "test", lateral_resistance=lateral_resistance)


@pytest.mark.parametrize("yaw_deg", [30.0, 150.0])
def test_a_slide_down_a_diagonal_balances_its_energy(yaw_deg):
    """Parked (wheels locked) on a 25 deg plane rising to the north, heading 30 deg off the contour (roll
    21.5, pitch +-13.1 deg), mu 0.3: the wheels hold it along its heading and it slides sideways. The
    potential energy it loses is the kinetic energy it gains plus the work of the sideways friction,
    ``sum(grip |v_y| dt)``, and of the wheels' braking, ``-sum(F_x v_x dt)`` (its front axle loaded, the
    slide's yaw moment turns it a little, and the part of its sliding velocity that turns into its heading
    is braked), to 0.1 % of the potential energy (the trapezoid of the mean speed). The moments that turn
    it are not in the balance: their work is the rotation's own energy (a rigid body's forces at its
    contacts do ``F . v + M w``, and ``M w`` is the rate of ``I w^2 / 2``)."""
    size = (160, 160)
    ys = (np.arange(size[0]) + 0.5) * RES
    elevation = np.broadcast_to(math.tan(math.radians(25.0)) * ys[:, np.newaxis], size).copy()
    plane = TerrainMap(elevation, np.zeros(size, np.uint8), np.zeros(size, bool), RES)
    body = RoverDynamics(plane, PARAMS, {0: ground_class(0.3)}, x=20.0, y=25.0, yaw=math.radians(yaw_deg))
    mass = PARAMS.mass_kg
    previous = body.step(DT, [0.0] * 6, VOLTS)
    pitch_at_start = previous.pitch_rad  # the slide's yaw moment then turns it a little (test_slide_yaw.py)
    y0 = body.y
    kinetic0 = 0.5 * mass * (previous.lateral_speed_mps**2 + previous.speed_mps**2)
    friction_work = 0.0
    for _ in range(150):
        step = body.step(DT, [0.0] * 6, VOLTS)
        grip = sideways_grip(
            np.array(step.normal_forces_n),
            np.array(step.traction_forces_n),
            0.3,
            np.zeros(6),
            step.speed_mps,  # as the kernel's step calls it: after the drive, before the slide
            step.yaw_rate_rps,
            PARAMS.effective_track_m,
            previous.lateral_speed_mps,
            PARAMS.wheelbase_m / 2.0,
        )
        friction_work += grip * abs(0.5 * (previous.lateral_speed_mps + step.lateral_speed_mps)) * DT
        # The body turns a little (the slide's yaw moment) and keeps its velocity over the ground, so part
        # of the slide turns into its heading, where the locked wheels brake it: their work too.
        friction_work -= sum(step.traction_forces_n) * 0.5 * (previous.speed_mps + step.speed_mps) * DT
        previous = step
    assert abs(math.degrees(pitch_at_start)) == pytest.approx(13.1, abs=0.1)
    assert abs(step.speed_mps) < 0.02 and step.lateral_speed_mps != 0.0
    potential = -mass * G * math.tan(math.radians(25.0)) * (body.y - y0)
    kinetic = 0.5 * mass * (step.lateral_speed_mps**2 + step.speed_mps**2) - kinetic0
    assert potential > 200.0  # J: it slid a metre and more
    assert potential == pytest.approx(kinetic + friction_work, rel=1e-3)


@pytest.mark.parametrize("turn", [1.0, -1.0])
def test_a_turn_past_the_grip_slides_to_the_outside(turn):
    """On the level (mu 0.15, no rolling resistance), at 1.5 m/s a hard arc asks ``v w`` past what the
    wheels hold sideways: the body slides to the outside of the turn (y right in a left turn), never in."""
    size = (200, 200)
    flat = TerrainMap(np.zeros(size), np.zeros(size, np.uint8), np.zeros(size, bool), RES)
    body = RoverDynamics(flat, PARAMS, {0: ground_class(0.15)}, x=10.0, y=25.0, yaw=0.0)
    for i in range(300):
        body.step(DT, [1.5 * min(1.0, i * DT / 2.0)] * 6, VOLTS)
    inner, outer = [0.3] * 3, [1.5] * 3
    wheels = inner + outer if turn > 0 else outer + inner
    steps = [body.step(DT, wheels, VOLTS) for _ in range(200)]
    assert all(turn * s.yaw_rate_rps >= 0.0 for s in steps)
    assert all(turn * s.lateral_speed_mps <= 0.0 for s in steps)
    assert min(turn * s.lateral_speed_mps for s in steps) < -0.02


def test_a_spinning_body_coasting_on_ice_keeps_its_velocity_over_the_ground():
    """Turning on firm ground, it coasts onto ice (mu 1e-9, no scrub): nothing acts on it, so its
    velocity over the ground stays what it was while its heading keeps turning, and the velocity in its
    own axes turns the other way (``dv_x/dt = v_y w``, ``dv_y/dt = - v_x w``). Tolerance: 1 % of the speed
    (the trapezoid of the heading over a step of a ~0.2 rad/s turn)."""
    size = (100, 200)
    classes = np.zeros(size, np.uint8)
    classes[:, 48:] = 1  # ice east of x = 12 m
    flat = TerrainMap(np.zeros(size), classes, np.zeros(size, bool), RES)
    grounds = {0: ground_class(0.8), 1: ground_class(1e-9, lateral_resistance=0.0)}
    body = RoverDynamics(flat, PARAMS, grounds, x=5.0, y=12.0, yaw=-0.3)
    for i in range(300):
        body.step(DT, [1.0 * min(1.0, i * DT / 2.0)] * 6, VOLTS)
    while body.x < 12.5:  # onto the ice on a gentle left arc
        body.step(DT, [0.9] * 3 + [1.1] * 3, VOLTS)
    track = []
    for _ in range(200):
        step = body.step(DT, [0.9] * 3 + [1.1] * 3, VOLTS)
        assert step.terrain_class == 1
        track.append((body.x, body.y, body.yaw, step.speed_mps, step.lateral_speed_mps))
    xs, ys, yaws = (np.array([t[i] for t in track]) for i in range(3))
    assert yaws[-1] - yaws[0] > 0.3  # it kept turning
    velocity = np.stack([np.diff(xs), np.diff(ys)], axis=1) / DT
    speed = float(np.hypot(*velocity[0]))
    assert speed > 0.5
    assert np.abs(velocity - velocity[0]).max() < 0.01 * speed
    # In its own axes the velocity turned against the heading: (v_x, v_y) = R(-yaw) v_ground.
    course = math.atan2(velocity[-1][1], velocity[-1][0])
    v_x, v_y = track[-1][3], track[-1][4]
    assert v_x == pytest.approx(speed * math.cos(course - yaws[-1]), abs=0.01 * speed)
    assert v_y == pytest.approx(speed * math.sin(course - yaws[-1]), abs=0.01 * speed)
