"""A seized wheel skids against the ground (``hil.traction``'s drag of a wheel turning apart from its side):
with one wheel locked and the others driving on level ground, it drags ``mu N`` against the rover's motion,
the other wheels pull that on top of the rolling resistance, its moment ``mu N track / 2`` turns the rover
toward it, its motor stays at the stall current, and with no wheel seized nothing changes.

Closed forms, from direct RoverDynamics / traction calls (no closed loop): on a class with no yaw scrub
(``lateral_resistance`` 0) and no sinkage, each side holds its own rolling resistance in the steady state
(the moment balance has nothing else), so the left side's two free wheels carry ``crr (N_LM + N_LR) +
mu N_LF``, the right side's three ``crr sum(N_R)``, each slips as the curve says for that, and the rover
yaws at ``u (s_L - s_R) / (track skid_factor)``.
"""

import hashlib
import itertools
import math

import numpy as np
import pytest

from hil import dynamics_kernel as k
from hil.dynamics import DynamicsStep, RoverDynamics
from hil.traction import (
    SLIP_SPEED_EPS_MPS,
    drive_forces,
    released_controls,
    resistance_coefficient,
    slip_for_ratio,
    traction_ratio,
)
from navigator.terrain import TerrainMap
from navigator.terrain_classes import FIRM, REFERENCE_WHEEL_LOAD_N, SANDY, TERRAIN_CLASSES, TerrainClass
from navigator.vehicle import VehicleParams

PARAMS = VehicleParams()
DT = 0.01
VOLTS = 24.0
# The motor model of RoverDynamics' defaults: gear 20, k_t 0.07 N m/A, 0.1 ohm, 10 A current limit.
GEAR, K_T, WINDING_OHM, LIMIT_A = 20.0, 0.07, 0.1, 10.0
LF_SEIZED = (1.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # the left front wheel locked, its motor commanded forward
# Firm ground's mu, crr and curve without the yaw scrub: the steady state is in closed form.
NO_SCRUB = {FIRM: TerrainClass(FIRM, "firm, no scrub", 0.8, 0.02, 1.0, "test", 0.05, 0.0, 1.0, 0.0)}


def plane(class_id: int = FIRM, size: tuple[int, int] = (200, 200), res: float = 0.25) -> TerrainMap:
    return TerrainMap(np.zeros(size), np.full(size, class_id, np.uint8), np.zeros(size, bool), res)


def seized_run(
    wheel: float,
    classes: dict[int, TerrainClass] = TERRAIN_CLASSES,
    class_id: int = FIRM,
    seconds: float = 6.0,
    stalled: tuple[float, ...] = LF_SEIZED,
) -> tuple[RoverDynamics, DynamicsStep]:
    """The rover driving from rest with the wheels at ``wheel`` m/s but a seized one (surface speed 0)."""
    body = RoverDynamics(plane(class_id), PARAMS, classes, x=25.0, y=25.0, yaw=0.0)
    wheels = [0.0 if s else wheel for s in stalled]
    for _ in range(round(seconds / DT)):
        step = body.step(DT, wheels, VOLTS, stalled)
    return body, step


def rolling_resistance(step: DynamicsStep, c: TerrainClass) -> tuple[float, float]:
    """The rolling resistance (N) of the left side's free wheels and of the right side's, at the step's
    loads (the seized one does not roll)."""
    n = step.normal_forces_n
    coefficients = [
        resistance_coefficient(
            n[i], REFERENCE_WHEEL_LOAD_N, c.rolling_resistance, c.sinkage_resistance, c.sinkage_exponent
        )
        for i in range(6)
    ]
    return coefficients[1] * n[1] + coefficients[2] * n[2], sum(coefficients[i] * n[i] for i in (3, 4, 5))


def closed_form(step: DynamicsStep, wheel: float, c: TerrainClass) -> tuple[float, float, float, float]:
    """The steady state with no scrub, from the step's wheel loads (LF seized, the others at ``wheel`` >
    0): (left free wheels' force / load, right wheels' force / load, speed, yaw rate)."""
    n = step.normal_forces_n
    mu, slip_constant = c.friction_mu, c.slip_constant
    left_rolling, right_rolling = rolling_resistance(step, c)
    left_ratio = (left_rolling + mu * n[0]) / (n[1] + n[2])
    right_ratio = right_rolling / (n[3] + n[4] + n[5])
    left_slip = slip_for_ratio(left_ratio, mu, slip_constant)
    right_slip = slip_for_ratio(right_ratio, mu, slip_constant)
    speed = wheel * (1.0 - 0.5 * (left_slip + right_slip))
    yaw_rate = wheel * (left_slip - right_slip) / PARAMS.effective_track_m
    return left_ratio, right_ratio, speed, yaw_rate


@pytest.mark.parametrize("wheel", [1.0, -0.8])
def test_a_seized_wheel_drags_mu_n_and_the_others_pull_it_on_top_of_the_rolling_resistance(wheel):
    """Driving forward or in reverse: its force is mu N against its ground motion (full slip), the body's
    force balance is the rolling resistance of the five turning wheels plus that drag, and its moment
    mu N track / 2 is held by the free wheels (left ones pulling harder), so the rover yaws toward it."""
    c = NO_SCRUB[FIRM]
    body, last = seized_run(wheel, NO_SCRUB)
    n, f = last.normal_forces_n, last.traction_forces_n
    direction = math.copysign(1.0, wheel)
    assert f[0] == -direction * c.friction_mu * n[0]  # exactly: full slip, the curve's mu
    assert last.slip[0] == -direction * 1.0
    left_rolling, right_rolling = rolling_resistance(last, c)
    rolling = left_rolling + right_rolling
    # Longitudinal balance (steady: no acceleration left): the free wheels pull the rolling resistance
    # plus the seized wheel's mu N; every wheel's force together, the resistance alone.
    assert abs(last.longitudinal_accel_mps2) < 1e-9
    assert sum(f[1:]) == pytest.approx(direction * (rolling + c.friction_mu * n[0]), rel=1e-9)
    assert sum(f) == pytest.approx(direction * rolling, rel=1e-9)
    # Yaw balance with no scrub: the wheels' moment (left wheels at -track / 2) cancels the rolling
    # resistance's, and in it the seized wheel's term is mu N track / 2 toward it (+: left).
    half_track = 0.5 * PARAMS.track_m
    seized_moment = -half_track * f[0]
    assert seized_moment == pytest.approx(direction * c.friction_mu * n[0] * half_track, rel=1e-12)
    free_moment = half_track * (sum(f[3:]) - f[1] - f[2])
    resist_moment = direction * half_track * (left_rolling - right_rolling)  # against each wheel's rolling
    assert free_moment + seized_moment + resist_moment == pytest.approx(0.0, abs=1e-7)
    # Each side's wheels as the curve says for what they carry, and the ground speeds their slips give.
    left_ratio, right_ratio, speed, yaw_rate = closed_form(last, abs(wheel), c)
    for i in (1, 2):
        assert f[i] / n[i] == pytest.approx(direction * left_ratio, rel=1e-9)
    for i in (3, 4, 5):
        assert f[i] / n[i] == pytest.approx(direction * right_ratio, rel=1e-9)
    assert body.speed == pytest.approx(direction * speed, rel=1e-9)
    assert body.yaw_rate == pytest.approx(direction * yaw_rate, rel=1e-6)
    assert direction * body.yaw_rate > 0.01  # toward the seized (left) side, reversing too


@pytest.mark.parametrize("class_id", [FIRM, SANDY])
def test_with_the_yaw_scrub_the_rover_still_turns_toward_the_seized_wheel_but_slower(class_id):
    """The scrub resists the turn: the rover yaws toward the seized side, slower than with no scrub at the
    same loads (the scrub takes from the left side's force, so the free wheels slip less), and a seized
    right wheel turns it the other way by as much."""
    c = TERRAIN_CLASSES[class_id]
    body, last = seized_run(1.0, class_id=class_id, seconds=8.0)
    assert last.traction_forces_n[0] == -c.friction_mu * last.normal_forces_n[0]
    *_, no_scrub_yaw_rate = closed_form(last, 1.0, c)
    assert 0.0 < body.yaw_rate < no_scrub_yaw_rate
    right, _ = seized_run(1.0, class_id=class_id, seconds=8.0, stalled=(0.0, 0.0, 0.0, 1.0, 0.0, 0.0))
    assert right.yaw_rate == pytest.approx(-body.yaw_rate, rel=1e-9)


def test_two_seized_wheels_on_a_side_both_drag_and_turn_the_rover_harder():
    """The seized wheels are the ones apart from their side, even where they are its median speed: each
    drags mu N, the side's turning wheel pulls against them, and the rover turns toward them harder than
    with one seized."""
    mu = TERRAIN_CLASSES[FIRM].friction_mu
    one, one_last = seized_run(1.0, seconds=4.0)
    two, last = seized_run(1.0, seconds=4.0, stalled=(1.0, 0.0, 1.0, 0.0, 0.0, 0.0))
    for i in (0, 2):
        assert last.traction_forces_n[i] == -mu * last.normal_forces_n[i]
        assert last.slip[i] == -1.0
    assert last.traction_forces_n[1] > 2.0 * one_last.traction_forces_n[1] > 0.0
    assert two.yaw_rate > 10.0 * one.yaw_rate > 0.0
    assert two.speed < one.speed


def test_the_drag_falls_smoothly_to_zero_as_the_rover_stops_over_a_locked_wheel():
    """A locked wheel's drag is the curve's force for its own slip, -v / max(v, SLIP_SPEED_EPS_MPS): mu N
    at full slip, and toward 0 with the ground speed below SLIP_SPEED_EPS_MPS (no jump); and near rest no
    more than half what stops its contact in a step (explicit Coulomb friction would chatter)."""
    body = RoverDynamics(plane(), PARAMS, x=25.0, y=25.0, yaw=0.0)
    ground = body._ground_table[FIRM]
    vehicle = body._body[k.VEHICLE : k.MOTOR]
    mu, slip_constant = ground[0], ground[1]
    mass, inertia, track = vehicle[0], vehicle[1], vehicle[2]
    stop_gain = 0.5 * mass * inertia / (inertia + mass * (0.5 * track) ** 2) / DT
    normals = np.full(6, 73.5)
    wheels = np.array([0.0, 0.3, 0.3, 0.3, 0.3, 0.3])
    drags = []
    for speed in (1e-5, 1e-4, 1e-3, 0.01, 0.049, 0.05, 0.2):
        out = np.zeros(6)
        drive_forces(
            wheels, normals, ground, vehicle, speed, 0.0, 0.0, DT, np.array(LF_SEIZED), out, 0.0,
            released_controls(vehicle[6]),
        )  # fmt: skip
        slip = -speed / max(speed, SLIP_SPEED_EPS_MPS)
        curve = -traction_ratio(slip, mu, slip_constant) * 73.5
        assert -out[0] == pytest.approx(min(curve, stop_gain * speed), rel=1e-12)
        drags.append(-out[0])
    assert drags[0] < 0.001 * 73.5  # 10 um/s over a locked wheel: 2e-4 of its load
    assert drags[3] < 0.5 * mu * 73.5 < drags[4]  # the stop bound below 1 cm/s of sliding, the curve above
    assert all(a < b for a, b in itertools.pairwise(drags[:-1]))
    assert drags[-2] == drags[-1] == pytest.approx(mu * 73.5, rel=1e-12)


def test_a_seized_wheel_records_full_slip_and_its_motor_the_stall_current_not_the_drags():
    """Its slip is -1 while the rover moves over it; its current the stall's (the current limit: the lock
    takes the drag, not the motor), and the pack pays the free motors' power plus I_max^2 R, nothing for
    the drag."""
    _, last = seized_run(1.0, seconds=3.0)
    assert last.slip[0] == -1.0
    assert last.motor_currents_a[0] == LIMIT_A
    assert last.duty[0] == pytest.approx(LIMIT_A * WINDING_OHM / VOLTS, rel=1e-12)
    power = LIMIT_A**2 * WINDING_OHM
    for i in range(1, 6):
        current = last.traction_forces_n[i] * PARAMS.wheel_radius_m / (GEAR * K_T)
        assert last.motor_currents_a[i] == pytest.approx(current, rel=1e-12)
        back_emf = K_T * GEAR * last.wheel_speeds_mps[i] / PARAMS.wheel_radius_m
        power += max(back_emf * current + current**2 * WINDING_OHM, 0.0)
    assert last.battery_current_a * VOLTS == pytest.approx(power, rel=1e-12)
    # The free wheels slip as the curve says for their (larger) pull: on the curve, below the limit.
    for i in range(1, 6):
        assert 0.0 < last.slip[i] < 0.1


# What a step's record says of the body's motion and its wheels (not the energy: how the pack is charged
# is another question, and changes of its own must not move these pins).
MOTION_FIELDS = (
    "x", "y", "yaw", "speed_mps", "lateral_speed_mps", "yaw_rate_rps", "slip", "normal_forces_n",
    "traction_forces_n", "motor_currents_a", "duty", "longitudinal_accel_mps2", "lateral_accel_mps2",
)  # fmt: skip


def step_digest(wheels: list[float], class_id: int, steps: int) -> str:
    """sha256 of every step's motion and wheel fields (their repr: the floats to the bit), from rest on
    level ground."""
    body = RoverDynamics(plane(class_id), PARAMS, x=25.0, y=25.0, yaw=0.0)
    digest = hashlib.sha256()
    for _ in range(steps):
        step = body.step(DT, wheels, VOLTS)
        digest.update(repr([getattr(step, name) for name in MOTION_FIELDS]).encode())
    return digest.hexdigest()


@pytest.mark.parametrize(
    ("wheels", "class_id", "expected"),
    [
        ([1.0] * 6, FIRM, "0e286425d0585b5369b283a7b463a8f5515b531c8585e09f27579bdc10dcc6e3"),
        ([0.6] * 3 + [1.0] * 3, FIRM, "1be904989595719200058426fb4a56f965ee041070318d9aa3153afa6aebb9bf"),
        ([-0.4] * 3 + [0.4] * 3, SANDY, "7d54d417ec49cc130d8a0a07654cb72ec90d33c66c27b29b47ff4233b690ddba"),
    ],
    ids=["straight", "arc", "turn-on-the-spot"],
)
def test_with_no_wheel_seized_the_steps_are_bit_for_bit_the_ones_before_the_drag(wheels, class_id, expected):
    """A side whose wheels turn alike has no wheel turning apart, so nothing drags: the motion and wheel
    fields of a straight run, an arc (4 s from rest) and a turn on the spot (3 s) are the ones at b9eb6c3,
    before the drag was modelled. A change to the physics that moves them on purpose re-pins them and
    says so."""
    assert step_digest(wheels, class_id, 400 if class_id == FIRM else 300) == expected


def test_a_wheel_its_controller_let_go_of_does_not_drag_only_a_seized_one_does() -> None:
    """A controller rebooting or past its command timeout slows its simulated wheel to 0, but a real VESC
    lets the motor go and the wheel rolls free: turning apart from its side without being seized, it gives
    nothing while its side pulls (held at zero pull by the sign of its slip), where the same wheel seized
    drags ``mu N``. Climbing, so the sides keep pulling forward as the rover slows; both front wheels, so
    neither side brakes to turn."""
    firm = TERRAIN_CLASSES[FIRM]
    grade = 0.2
    size = (200, 200)
    xs = (np.arange(size[1]) + 0.5) * 0.25
    uphill = TerrainMap(
        np.broadcast_to(grade * xs[np.newaxis, :], size).copy(),
        np.full(size, FIRM, np.uint8),
        np.zeros(size, bool),
        0.25,
    )
    forces, loads = {}, {}
    for seized in (False, True):
        body = RoverDynamics(uphill, PARAMS, x=5.0, y=25.0, yaw=0.0)  # facing uphill
        for _ in range(300):
            body.step(DT, [0.5] * 6, VOLTS)
        fronts_seized = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0)
        step = body.step(DT, [0.0, 0.5, 0.5, 0.0, 0.5, 0.5], VOLTS, fronts_seized if seized else ())
        assert sum(step.traction_forces_n[1:3]) > 0.0  # its side pulls
        forces[seized], loads[seized] = step.traction_forces_n[0], step.normal_forces_n[0]
    assert forces[False] == 0.0
    assert forces[True] == pytest.approx(-firm.friction_mu * loads[True], rel=1e-6)
