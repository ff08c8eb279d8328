"""The compiled physics step (hil.dynamics_kernel): what moved into it from Python, and its cache key."""

import math

import numpy as np
import pytest

from hil import dynamics_kernel
from hil.battery import REGEN_CURRENT_LIMIT_A
from hil.dynamics import DynamicsError, DynamicsStep, RoverDynamics
from hil.dynamics_kernel import BodyState
from navigator.footprint import BOUNDARY, CLEAR, OBSTACLE
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TerrainClass
from navigator.vehicle import VehicleParams, tilt_margins, tilt_margins_kernel

PARAMS = VehicleParams()


def slope(grade_x: float) -> TerrainMap:
    size = (60, 60)
    xs = (np.arange(size[1]) + 0.5) * 0.25
    elevation = np.broadcast_to(grade_x * xs[np.newaxis, :], size).copy()
    return TerrainMap(elevation, np.zeros(size, np.uint8), np.zeros(size, bool), 0.25)


def test_motor_input_current_is_the_sum_of_the_drawing_motors_current_times_duty():
    """The world charges the pack with it: each motor's I x duty, a braking (generating) motor's negative,
    down to its controller's regeneration floor."""
    body = RoverDynamics(slope(-0.15), PARAMS, x=7.5, y=7.5, yaw=0.0)  # facing downhill
    braking = drawing = 0
    stalled = (0.0, 1.0, 0.0, 0.0, 0.0, -1.0)
    for i in range(300):
        wheels = [0.3] * 6 if i < 200 else [0.8, 0.8, 0.8, -0.2, -0.2, -0.2]
        step = body.step(0.01, wheels, 24.0, stalled if i >= 250 else ())
        terms = [current * duty for current, duty in zip(step.motor_currents_a, step.duty, strict=True)]
        assert step.motor_input_current_a == sum([max(term, -REGEN_CURRENT_LIMIT_A) for term in terms])
        braking += any(term < 0.0 for term in terms)
        drawing += any(term > 0.0 for term in terms)
    assert braking > 0 and drawing > 0  # both kinds of motor were summed


def test_the_compiled_tilt_margins_are_the_planners_bit_for_bit():
    rng = np.random.default_rng(3)
    for force in rng.uniform(-12.0, 12.0, (500, 3)).tolist():
        expected = tilt_margins(PARAMS.tip_roll_rad, PARAMS.tip_pitch_rad, *force)
        got = tilt_margins_kernel(PARAMS.tip_roll_rad, PARAMS.tip_pitch_rad, *force)
        assert got == expected


@pytest.mark.parametrize("degrees", [5.0, 70.0])
def test_specific_force_at_rest_is_gravity_in_body_axes_rolled_over_or_not(degrees):
    grade = math.tan(math.radians(degrees))
    # Across the slope: it rolls. On ground that holds it at rest even at 70 deg (on firm ground it would
    # slide, and slide rather than tip: tests/hil/test_sideways_slide.py).
    grippy = {0: TerrainClass(0, "grippy", 3.0, 0.02, 1.0, "test")}
    body = RoverDynamics(slope(grade), PARAMS, grippy, x=7.5, y=7.5, yaw=math.pi / 2.0)
    for _ in range(3):
        step = body.step(0.01, [0.0] * 6, 24.0)
    roll = step.roll_rad
    assert step.rollover == (degrees > 45.0)
    expected = (0.0, 9.81 * math.sin(roll), 9.81 * math.cos(roll))
    assert step.specific_force_body_mps2 == pytest.approx(expected, abs=0.05)


def test_a_swapped_in_terrain_with_a_class_the_table_lacks_is_a_typed_error():
    """The kernel indexes its class table with the class under the rover unchecked: the table must cover
    every class on a new map as on the first."""
    ice = {0: TerrainClass(0, "ice", 0.1, 0.02, 1.0, "test")}
    body = RoverDynamics(slope(0.0), PARAMS, ice, x=7.5, y=7.5, yaw=0.0)
    other = slope(0.0)
    classes = np.array(other.terrain_class)
    classes[:, 40:] = 1
    with pytest.raises(DynamicsError, match=r"terrain classes \[1\]"):
        body.set_terrain(TerrainMap(other.elevation_m, classes, np.zeros(classes.shape, bool), 0.25))
    body.step(0.01, [0.2] * 6, 24.0)  # still on its old map


def _record_read_back(body: RoverDynamics, before: BodyState, voltage: float) -> DynamicsStep:
    """The step just taken as read back from the kernel's vector in Python (the form the compiled record
    replaced): one ``tolist()``, the layout's indices, the contact kind's name from a table."""
    v = body._values.tolist()
    k = dynamics_kernel
    touching = v[k.TOUCHING] != 0.0
    kinds = {CLEAR: "", BOUNDARY: "boundary", OBSTACLE: "obstacle"}
    wheels, slip, normals, traction, currents, duty = (
        tuple(v[start : start + 6]) for start in (k.WHEELS, k.SLIP, k.NORMALS, k.TRACTION, k.CURRENTS, k.DUTY)
    )
    return DynamicsStep(
        v[k.X],
        v[k.Y],
        v[k.YAW],
        v[k.SPEED],
        v[k.LATERAL_SPEED],
        v[k.YAW_RATE],
        v[k.ROLL],
        v[k.PITCH],
        before.class_id,
        wheels,
        slip,
        normals,
        traction,
        currents,
        duty,
        v[k.STEP_ACCEL],
        v[k.LATERAL],
        (v[k.FORCE_X], v[k.FORCE_Y], v[k.FORCE_Z]),
        v[k.ROLL_MARGIN],
        v[k.PITCH_MARGIN],
        body.rolled_over,
        v[k.ROLLOVER_STARTED] != 0.0,
        touching,
        v[k.CONTACT_BEGAN] != 0.0,
        kinds[int(v[k.CONTACT_KIND])] if touching else "",
        v[k.ENERGY_J] / 3600.0,
        v[k.POWER_W] / voltage if voltage > 0.0 else 0.0,
        v[k.INPUT_CURRENT_A],
        tuple(v[k.SPEED_LIMITS : k.SPEED_LIMITS + 6]),
        (tuple(v[k.HELD_FLOORS : k.HELD_FLOORS + 6]), tuple(v[k.HELD_CEILINGS : k.HELD_CEILINGS + 6])),
        body._class_names[before.class_id],
    )


def test_the_compiled_step_record_is_the_vector_read_back_bit_for_bit():
    """The kernel boxes the step's record and the body's state itself; they must be the vector's numbers,
    field by field and of the same types, through contacts (walls, the map edge), seized wheels, a rough
    slope with two classes, and rollovers."""
    rng = np.random.default_rng(11)
    size = (60, 60)
    classes = np.zeros(size, np.uint8)
    classes[:, 30:] = 1
    obstacles = np.zeros(size, bool)
    obstacles[14:18, :] = True  # a wall along x from y = 3.5 m, 1 m north of the start
    two = {
        0: TerrainClass(0, "grass", 0.7, 0.05, 1.0, "test"),
        1: TerrainClass(1, "sand", 0.4, 0.12, 1.0, "test"),
    }
    compared = contacts = rollovers = 0
    for trial in range(12):
        # Gentle slopes to rollover-steep ones, across the two classes.
        elevation = np.cumsum(rng.uniform(-0.02, 0.02 + 0.04 * trial, size), axis=1)
        terrain = TerrainMap(elevation, classes, obstacles, 0.25)
        body = RoverDynamics(terrain, PARAMS, two, x=7.4, y=2.5, yaw=float(rng.uniform(-3, 3)))
        for i in range(400):
            before = body._state
            if body.rolled_over:
                break
            if i % 40 == 0:  # a command held for 0.4 s, so the body gets somewhere
                wheels = rng.uniform(-1.5, 1.5, 6).tolist()
            stalled = tuple(rng.choice([-1.0, 0.0, 1.0], 6).tolist()) if rng.random() < 0.2 else ()
            voltage = float(rng.choice([24.0, 0.0])) if rng.random() < 0.05 else 24.0
            step = body.step(0.01, wheels, voltage, stalled)  # the map's edge stops it: it never leaves
            expected = _record_read_back(body, before, voltage)
            assert [(type(f), f) for f in step] == [(type(f), f) for f in expected]
            state = dynamics_kernel.state(body._values)
            assert tuple(body._state) == state and [type(f) for f in state] == [type(f) for f in body._state]
            compared += 1
            contacts += step.collided
            rollovers += step.rollover_started
    assert compared > 1000 and contacts > 0 and rollovers > 0
