"""The motors' voltage limit on wheel speed (hil.motor_voltage): ``k_e omega + I R <= duty_max V``.

Closed forms on level firm ground (crr 0.02, no sinkage part), the default rover and motors (k_t 0.07 N m/A,
gear 20, 0.1 ohm, wheel radius 0.11 m, duty max 0.95): a wheel's steady pull is ``crr N`` with
``N = m g / 6``, its current ``crr N r / (gear k_t)``, its speed limit ``r / (gear k_t) (0.95 V - I R)``
and the ground speed that less the curve's slip for ``F / N = crr``.
"""

from __future__ import annotations

import hashlib
import math
import struct

import numpy as np
import pytest

from firmware_bridge.can_link import CanLink
from hil.dynamics import DEFAULT_MAX_DUTY, DynamicsError, RoverDynamics
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
K_T, GEAR, RESISTANCE = 0.07, 20.0, 0.1  # RoverDynamics' defaults
LOW_VOLTS = 18.0  # a sagging pack: its limit, ~1.34 m/s, is below the 1.5 m/s commanded
TOP_SPEED = 1.5


def plane(grade_x: float = 0.0, class_id: int = FIRM, size: tuple[int, int] = (80, 160)) -> TerrainMap:
    res = 0.25
    xs = (np.arange(size[1]) + 0.5) * res
    elevation = np.broadcast_to(grade_x * xs[np.newaxis, :], size).copy()
    return TerrainMap(elevation, np.full(size, class_id, np.uint8), np.zeros(size, bool), res)


def level_limit_mps(volts: float) -> tuple[float, float]:
    """(wheel surface speed, ground speed) of the default rover held at its voltage limit on level firm
    ground, from the closed form in the module docstring."""
    firm = TERRAIN_CLASSES[FIRM]
    load = PARAMS.mass_kg * G / 6.0
    current = firm.rolling_resistance * load * PARAMS.wheel_radius_m / (GEAR * K_T)
    surface = PARAMS.wheel_radius_m / (GEAR * K_T) * (DEFAULT_MAX_DUTY * volts - current * RESISTANCE)
    slip = slip_for_ratio(firm.rolling_resistance, firm.friction_mu, firm.slip_constant)
    return surface, surface * (1.0 - slip)


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_commanded_past_the_voltage_limit_the_rover_settles_at_the_back_emf_speed(direction):
    """Tolerance: 1e-9 m/s on the wheel speed, 1e-6 m/s on the ground speed (after 6 s, 60 drive time
    constants; the limit uses the last step's current, which is steady by then)."""
    body = RoverDynamics(plane(), PARAMS, x=20.0, y=10.0, yaw=0.0)
    for _ in range(600):
        step = body.step(DT, [direction * TOP_SPEED] * 6, LOW_VOLTS)
    surface, ground = level_limit_mps(LOW_VOLTS)
    assert surface < TOP_SPEED - 0.1
    assert step.wheel_speeds_mps == pytest.approx([direction * surface] * 6, abs=1e-9)
    assert step.wheel_speed_limits_mps == pytest.approx([surface] * 6, abs=1e-9)
    assert body.speed == pytest.approx(direction * ground, abs=1e-6)
    assert step.duty == pytest.approx([direction * DEFAULT_MAX_DUTY] * 6, abs=1e-9)


def test_the_default_rover_reaches_top_speed_down_to_20_1_volts():
    """The docs' figure: 1.5 m/s on level firm ground needs 20.11 V at the terminals; below, it is slower."""
    surface, _ = level_limit_mps(20.11)
    assert surface == pytest.approx(TOP_SPEED, abs=1e-3)
    for volts in (20.2, 20.0):
        body = RoverDynamics(plane(), PARAMS, x=20.0, y=10.0, yaw=0.0)
        for _ in range(300):
            step = body.step(DT, [TOP_SPEED] * 6, volts)
        if volts > 20.11:
            assert step.wheel_speeds_mps == (TOP_SPEED,) * 6  # the command's floats
        else:
            assert step.wheel_speeds_mps == pytest.approx([level_limit_mps(volts)[0]] * 6, abs=1e-9)
            assert max(step.wheel_speeds_mps) < TOP_SPEED - 0.005


def _run_hash(voltage: float, max_duty: float) -> str:
    """sha256 of a 4 s run's records at ``voltage`` with the controllers' top duty ``max_duty``:
    accelerating to 1.5 m/s, turning, reversing, up and down a 10 % sandy slope."""
    body = RoverDynamics(plane(0.1, SANDY), PARAMS, x=20.0, y=10.0, yaw=0.3, max_duty=max_duty)
    digest = hashlib.sha256()
    for i in range(400):
        t = i * DT
        if t < 1.5:
            wheels = [TOP_SPEED] * 6
        elif t < 2.5:
            wheels = [0.6, 0.6, 0.6, 1.5, 1.5, 1.5]
        else:
            wheels = [-1.2] * 6
        step = body.step(DT, wheels, voltage)
        numbers = (
            step.x, step.y, step.yaw, step.speed_mps, step.lateral_speed_mps, step.yaw_rate_rps,
            *step.wheel_speeds_mps, *step.slip, *step.normal_forces_n, *step.traction_forces_n,
            *step.motor_currents_a, *step.duty, step.energy_wh, step.motor_input_current_a,
        )  # fmt: skip
        digest.update(struct.pack(f"<{len(numbers)}d", *numbers))
    return digest.hexdigest()


def test_below_the_limit_a_run_keeps_every_float():
    """At 21 V the run's duty reaches 0.925: near the 0.95 limit, never at it, it is the same run with a
    top duty of 1 to the bit; at 19 V the top duty binds and the two differ. (The run before the limit
    existed, at commit c46714a, hashed the same as at 21 V here.)"""
    assert _run_hash(21.0, DEFAULT_MAX_DUTY) == _run_hash(21.0, 1.0)
    assert _run_hash(19.0, DEFAULT_MAX_DUTY) != _run_hash(19.0, 1.0)


@pytest.fixture
def buses(request):
    with virtual_bus_pair(request.node.name) as pair:
        yield pair


def test_the_vescs_report_the_limited_speed_and_the_top_duty(buses):
    """Through the simulated VESCs on a CAN bus, as the world wires them: STATUS's speed is the wheel speed
    the physics applied (within the ERPM field's 1 ERPM), its duty the top duty (0.001 resolution)."""
    body = RoverDynamics(plane(), PARAMS, x=20.0, y=10.0, yaw=0.0)
    clock, sink = SimClock(), MemorySink()
    companion_bus, sim_bus = buses
    codec = make_codec()
    link = CanLink(companion_bus, codec, clock, sink)
    vescs = SimVescBank(sim_bus, codec, clock)
    for _ in range(400):
        link.send_wheel_speeds([TOP_SPEED] * 6)
        vescs.poll()
        clock.advance(to_ns(DT))
        step = body.step(DT, vescs.wheel_speeds_mps(), LOW_VOLTS)
        vescs.set_electrical(step.motor_currents_a, LOW_VOLTS, step.duty, step.wheel_speed_limits_mps)
        vescs.step(DT)
        link.poll()
    surface, _ = level_limit_mps(LOW_VOLTS)
    one_erpm = 1.0 / codec.profile.erpm_per_mps
    readings = link.readings()
    assert [r.speed_mps for r in readings] == pytest.approx(step.wheel_speeds_mps, abs=one_erpm)
    assert [r.speed_mps for r in readings] == pytest.approx([surface] * 6, abs=one_erpm)
    assert [r.duty for r in readings] == pytest.approx([DEFAULT_MAX_DUTY] * 6, abs=1e-3)


@pytest.mark.parametrize("max_duty", [0.0, -0.5, 1.01, math.nan])
def test_a_top_duty_outside_0_to_1_is_a_dynamics_error(max_duty):
    with pytest.raises(DynamicsError, match="max_duty"):
        RoverDynamics(plane(), PARAMS, x=20.0, y=10.0, yaw=0.0, max_duty=max_duty)


@pytest.mark.parametrize("limits", [[1.0] * 5, [1.0] * 5 + [-0.1], [1.0] * 5 + [math.nan]])
def test_the_vescs_refuse_speed_limits_that_are_not_six_non_negative_numbers(buses, limits):
    vescs = SimVescBank(buses[1], make_codec(), SimClock())
    with pytest.raises(ValueError, match="speed limits"):
        vescs.set_electrical([0.0] * 6, 24.0, [0.0] * 6, limits)
