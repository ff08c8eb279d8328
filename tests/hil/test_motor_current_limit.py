"""The motors' current limit on wheel speed (hil.motor_current): a wheel whose pull its motor's current
limit caps, not the ground's ``mu N``, turns at the speed where the traction curve gives that pull.

Closed forms for the default rover (45 kg, k_t 0.07 N m/A, gear 20, wheel radius 0.11 m): a wheel's pull
at the current limit ``I`` is ``F_cap = I k_t gear / r`` (12.73 N per A). On a slope of ``theta`` the rover
climbs if ``6 F_cap > m g (sin theta + crr cos theta)``, rolls back if ``6 F_cap < m g (sin theta - crr
cos theta)``, and between the two it stalls: its wheels hardly turn, so their rolling resistance (which
fades in over ``ROLLING_SPEED_EPS_MPS`` of turning) holds the difference. A stalled wheel slips by the curve's
slip for ``F_cap / N`` (``slip_for_ratio``), and turns at ``v / (1 - s)`` over a ground speed ``v >= 0``,
``v (1 - s)`` over one < 0 (turned backwards while it pulls forwards).

The default limit (10 A: 127 N a wheel) is above ``mu N`` of every class at the default loads (at most
0.8 x 73.6 N = 59 N), so the ground caps first there; the tests that need the motors to cap first set a
lower limit.
"""

from __future__ import annotations

import hashlib
import math
import struct

import can
import numpy as np
import pytest

from firmware_bridge.can_link import CanLink
from hil.dynamics import DynamicsStep, RoverDynamics
from hil.motor_current import hold_at_current_limit
from hil.traction import slip_for_ratio
from hil.vesc_sim import SimVescBank
from logs.clock import SimClock, to_ns
from logs.sink import MemorySink
from navigator.terrain import TerrainMap
from navigator.terrain_classes import FIRM, SANDY, TERRAIN_CLASSES
from navigator.vehicle import G, VehicleParams
from tests.firmware_bridge.virtual_can import make_codec, virtual_bus_pair

PARAMS = VehicleParams()
DT = 0.01
K_T, GEAR = 0.07, 20.0  # RoverDynamics' defaults
NEWTONS_PER_AMP = K_T * GEAR / PARAMS.wheel_radius_m
VOLTS = 24.0
FIRM_GROUND = TERRAIN_CLASSES[FIRM]
# 15 deg of firm ground: a climb needs 19.0-19.5 N a wheel, so 1.5 A (19.1 N) stalls on it; the least
# loaded wheel (the front, ~47 N) could take 37 N from the ground, so the motors cap first.
STALL_SLOPE_RAD = math.radians(15.0)
STALL_AMPS = 1.5


def plane(grade_x: float, class_id: int, size: tuple[int, int] = (80, 160)) -> TerrainMap:
    res = 0.25
    xs = (np.arange(size[1]) + 0.5) * res
    elevation = np.broadcast_to(grade_x * xs[np.newaxis, :], size).copy()
    return TerrainMap(elevation, np.full(size, class_id, np.uint8), np.zeros(size, bool), res)


@pytest.fixture
def buses(request):
    with virtual_bus_pair(request.node.name) as pair:
        yield pair


def drive_through_vescs(
    body: RoverDynamics, buses: tuple[can.BusABC, can.BusABC], command_mps: float, seconds: float
) -> tuple[DynamicsStep, list[float], list[float], float]:
    """Command ``command_mps`` on all six wheels over CAN for ``seconds``, the simulated VESCs turning them
    as the world wires them; returns the last step, the VESCs' last reports (m/s), the body's x at each
    second and one ERPM in m/s (the reports' resolution)."""
    clock, sink = SimClock(), MemorySink()
    companion_bus, sim_bus = buses
    codec = make_codec()
    link = CanLink(companion_bus, codec, clock, sink)
    vescs = SimVescBank(sim_bus, codec, clock)
    xs = []
    for i in range(round(seconds / DT)):
        link.send_wheel_speeds([command_mps] * 6)
        vescs.poll()
        clock.advance(to_ns(DT))
        step = body.step(DT, vescs.wheel_speeds_mps(), VOLTS)
        limits = step.wheel_speed_limits_mps
        vescs.set_electrical(step.motor_currents_a, VOLTS, step.duty, limits, step.held_speeds_mps)
        vescs.step(DT)
        link.poll()
        if i % 100 == 0:
            xs.append(body.x)
    return step, [r.speed_mps for r in link.readings()], xs, 1.0 / codec.profile.erpm_per_mps


def test_a_climb_past_the_motors_current_limit_stalls_with_the_wheels_nearly_still(buses):
    """1.5 A on 15 deg of firm ground (the closed forms in the module docstring): the rover stands, its
    wheels' pull at the limit, each slipping by the curve's slip for its pull / load (1e-9) and turning at
    the speed that slip gives over the ground (1e-9 m/s), which the VESCs report (within 1 ERPM): under
    1 cm/s. Before the limit held the wheels, they turned (and were reported) at the 1.0 m/s commanded,
    and the rover rolled back down the slope."""
    cap = STALL_AMPS * NEWTONS_PER_AMP
    weight = PARAMS.mass_kg * G
    crr = FIRM_GROUND.rolling_resistance
    climb, roll_back = (
        weight * (math.sin(STALL_SLOPE_RAD) + s * crr * math.cos(STALL_SLOPE_RAD)) for s in (1, -1)
    )
    assert roll_back < 6.0 * cap < climb  # the closed form's stall
    body = RoverDynamics(
        plane(math.tan(STALL_SLOPE_RAD), FIRM),
        PARAMS,
        x=20.0,
        y=10.0,
        yaw=0.0,
        motor_current_limit_a=STALL_AMPS,
    )
    step, reported, xs, one_erpm = drive_through_vescs(body, buses, 1.0, 6.0)

    assert (
        max(step.normal_forces_n) * FIRM_GROUND.friction_mu
        > min(step.normal_forces_n) * FIRM_GROUND.friction_mu
        > cap
    )
    assert step.traction_forces_n == pytest.approx([cap] * 6, rel=1e-9)
    expected_slip = [
        slip_for_ratio(cap / n, FIRM_GROUND.friction_mu, FIRM_GROUND.slip_constant)
        for n in step.normal_forces_n
    ]
    assert step.slip == pytest.approx(expected_slip, abs=1e-9)
    assert max(expected_slip) < 0.05  # small: the ground holds the pull easily
    v = step.speed_mps
    held = [v / (1.0 - s) if v >= 0.0 else v * (1.0 - s) for s in expected_slip]
    assert step.wheel_speeds_mps == pytest.approx(held, abs=1e-9)
    assert step.held_speeds_mps[1] == pytest.approx(held, abs=1e-9)  # the ceilings: pulling forwards
    assert reported == pytest.approx(step.wheel_speeds_mps, abs=one_erpm)
    assert max(abs(r) for r in reported) < 0.01
    assert abs(xs[-1] - xs[2]) < 0.03  # over the last 3 s: it stands


def _run_hash(amps: float, peak: list[float] | None = None) -> str:
    """sha256 of a 4 s run's records with the motors' current limit ``amps``: accelerating to 1.5 m/s,
    turning, reversing, up and down a 10 % slope of firm ground. ``peak``: gets the largest pull of a wheel
    (N) appended."""
    body = RoverDynamics(plane(0.1, FIRM), PARAMS, x=20.0, y=10.0, yaw=0.3, motor_current_limit_a=amps)
    digest = hashlib.sha256()
    largest = 0.0
    for i in range(400):
        t = i * DT
        if t < 1.5:
            wheels = [1.5] * 6
        elif t < 2.5:
            wheels = [0.6, 0.6, 0.6, 1.5, 1.5, 1.5]
        else:
            wheels = [-1.2] * 6
        step = body.step(DT, wheels, VOLTS)
        largest = max(largest, *(abs(f) for f in step.traction_forces_n))
        numbers = (
            step.x, step.y, step.yaw, step.speed_mps, step.lateral_speed_mps, step.yaw_rate_rps,
            *step.wheel_speeds_mps, *step.slip, *step.normal_forces_n, *step.traction_forces_n,
            *step.motor_currents_a, *step.duty, step.energy_wh, step.motor_input_current_a,
            *step.held_speeds_mps[0], *step.held_speeds_mps[1],
        )  # fmt: skip
        digest.update(struct.pack(f"<{len(numbers)}d", *numbers))
    if peak is not None:
        peak.append(largest)
    return digest.hexdigest()


def test_below_the_limit_a_run_keeps_every_float():
    """The same run with a limit just above its largest pull and with one far higher (1000 A) is the same to
    the bit; with the limit below that pull the two differ."""
    peak: list[float] = []
    far = _run_hash(1000.0, peak)
    (largest,) = peak
    assert _run_hash(1.001 * largest / NEWTONS_PER_AMP) == far
    assert _run_hash(0.9 * largest / NEWTONS_PER_AMP) != far


def test_where_the_ground_caps_first_the_wheels_spin_at_the_command(buses):
    """20 deg of sand (too steep for it: tan 20 deg = 0.36 > mu - crr = 0.28) at the default 10 A: every
    wheel's pull is the ground's mu N, no current limit holds one, and the wheels spin at the 1.0 m/s
    commanded (the VESCs report it, within 1 ERPM) while the rover slides back: the dig-in as before."""
    sand = TERRAIN_CLASSES[SANDY]
    body = RoverDynamics(plane(math.tan(math.radians(20.0)), SANDY), PARAMS, x=20.0, y=10.0, yaw=0.0)
    step, reported, _, one_erpm = drive_through_vescs(body, buses, 1.0, 3.0)
    assert step.traction_forces_n == pytest.approx(
        [sand.friction_mu * n for n in step.normal_forces_n], rel=1e-9
    )
    assert step.held_speeds_mps == ((-math.inf,) * 6, (math.inf,) * 6)
    assert step.wheel_speeds_mps == pytest.approx([1.0] * 6, abs=one_erpm)  # SET_RPM: whole ERPM
    assert reported == pytest.approx([1.0] * 6, abs=one_erpm)
    assert body.speed < 0.0 and min(step.slip) == 1.0


# hold_at_current_limit on its own: a wheel of 100 N load on ground of mu 0.8, slip constant 0.05, its
# motor capping its pull at 40 N (below mu N = 80 N); the curve's slip for 40 / 100.
GROUND = np.array([0.8, 0.05, 0.02, 0.0, 1.0, 0.4])
CAP = 40.0
SLIP = slip_for_ratio(CAP / 100.0, 0.8, 0.05)


@pytest.mark.parametrize(
    ("force", "ground_speed", "given", "expected", "floor_or_ceiling"),
    [
        (CAP, 0.5, 1.5, 0.5 / (1.0 - SLIP), "ceiling"),  # pulling uphill: the ground lags the wheel
        (CAP, -0.5, 1.5, -0.5 * (1.0 - SLIP), "ceiling"),  # pulling forwards, turned backwards
        (-CAP, 0.5, 0.0, 0.5 * (1.0 - SLIP), "floor"),  # braking at the limit: the ground turns it on
        (-CAP, -0.5, -1.5, -0.5 / (1.0 - SLIP), "floor"),  # pulling in reverse
        (CAP, 0.5, 0.4, 0.4, "ceiling"),  # given less than the held speed: it turns as given
    ],
)
def test_a_held_wheel_turns_where_the_curve_gives_its_capped_pull(
    force, ground_speed, given, expected, floor_or_ceiling
):
    """The module's closed forms, on the middle left wheel (its ground speed is the body's with no turn);
    the slip of the speed held, ``(u - v) / max(|u|, |v|)``, is the curve's for the pull (1e-12)."""
    wheels = np.full(6, given)
    forces = np.full(6, force)
    floors, ceilings = np.empty(6), np.empty(6)
    hold_at_current_limit(
        wheels, forces, np.full(6, 100.0), np.zeros(6), ground_speed, 0.0, 0.5, GROUND, CAP, floors, ceilings
    )
    assert wheels[1] == pytest.approx(expected, rel=1e-12)
    held = ceilings if floor_or_ceiling == "ceiling" else floors
    other = floors if floor_or_ceiling == "ceiling" else ceilings
    u = held[1]
    assert abs(u - ground_speed) / max(abs(u), abs(ground_speed)) == pytest.approx(SLIP, rel=1e-12)
    assert math.isinf(other[1])


def test_no_hold_below_the_cap_where_the_ground_caps_or_on_a_seized_wheel():
    """Pulls below the cap, a cap at or past mu N (the ground's limit comes first: the wheel may spin), and
    a seized wheel (its lock holds it) keep the speeds given and hold nothing."""
    wheels = np.full(6, 1.5)
    forces = np.array([CAP * 0.99, CAP, CAP, CAP, CAP, CAP])
    normals = np.array([100.0, 100.0, CAP / 0.8, 30.0, 100.0, 100.0])  # wheel 2: mu N = cap; 3: below it
    locked = np.array([0.0, 0.0, 0.0, 0.0, 1.0, 0.0])
    floors, ceilings = np.empty(6), np.empty(6)
    hold_at_current_limit(wheels, forces, normals, locked, 0.5, 0.0, 0.5, GROUND, CAP, floors, ceilings)
    assert wheels.tolist() == [1.5, 0.5 / (1.0 - SLIP), 1.5, 1.5, 1.5, 0.5 / (1.0 - SLIP)]
    assert floors.tolist() == [-math.inf] * 6
    assert [i for i in range(6) if math.isfinite(ceilings[i])] == [1, 5]
