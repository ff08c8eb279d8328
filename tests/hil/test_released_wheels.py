"""A wheel its controller lets go of rolls with the ground; the battery cut-off and the under-voltage fault.

Closed forms on firm ground (mu 0.8, crr 0.02, no sinkage part, so every wheel's rolling resistance is
``crr N`` whatever its load): six released wheels roll the rover at ``g (sin - crr cos)`` down a slope and
slow it by ``g crr`` on the level; a brake current ``I`` takes ``6 I k_t gear / r`` more, and holds the rover
where that is at least ``m g sin``. The controllers here are ``SimVescBank``'s, on a virtual CAN bus, so a
timeout is a real one: the rover's link stops sending.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator
from contextlib import ExitStack
from dataclasses import dataclass

import numpy as np
import pytest

from firmware_bridge.can_link import CanLink
from hil.dynamics import DynamicsStep, RoverDynamics
from hil.vesc_limits import DEFAULT_TIMEOUT_BRAKE_CURRENT_A, DRIVEN, SupplyLimits, VescLimitsError
from hil.vesc_sim import SimVescBank
from logs.clock import SimClock, to_ns
from logs.sink import MemorySink
from navigator.terrain import TerrainMap
from navigator.vehicle import VehicleParams
from tests.firmware_bridge.virtual_can import make_codec, virtual_bus_pair
from tests.hil.world_harness import run_world

PARAMS = VehicleParams()
DT = 0.01
G, CRR = 9.81, 0.02  # navigator.vehicle.G; firm ground's rolling resistance
K_T, GEAR = 0.07, 20.0  # RoverDynamics' motor defaults
NEWTONS_PER_AMP = K_T * GEAR / PARAMS.wheel_radius_m
PACK_V = 24.0


def plane(slope_deg: float, size: int = 400, res: float = 0.25) -> TerrainMap:
    """Firm ground rising ``slope_deg`` to the east (+x)."""
    xs = (np.arange(size) + 0.5) * res
    elevation = np.broadcast_to(math.tan(math.radians(slope_deg)) * xs[np.newaxis, :], (size, size)).copy()
    return TerrainMap(elevation, np.zeros((size, size), np.uint8), np.zeros((size, size), bool), res)


@dataclass
class Rover:
    """A rover body driven by six simulated VESCs, commanded over CAN by the rover's own link."""

    body: RoverDynamics
    bank: SimVescBank
    link: CanLink
    clock: SimClock
    voltage_v: float = PACK_V
    last: DynamicsStep | None = None

    def run(self, seconds: float, speeds: list[float] | None = None) -> list[DynamicsStep]:
        """Lockstep at 100 Hz: the link sends ``speeds`` (None: nothing, the link is silent), the
        controllers and the body step, the link reads the status."""
        steps = []
        for _ in range(round(seconds / DT)):
            if speeds is not None:
                self.link.send_wheel_speeds(speeds)
            bank, body = self.bank, self.body
            bank.poll()
            step = body.step(
                DT, bank.wheel_speeds_mps(), self.voltage_v, bank.stalled(), bank.wheel_controls()
            )
            bank.set_rolling_speeds(step.wheel_speeds_mps)
            bank.set_electrical(
                step.motor_currents_a, self.voltage_v, step.duty, step.wheel_speed_limits_mps,
                step.held_speeds_mps,
            )  # fmt: skip
            self.clock.advance(to_ns(DT))
            bank.step(DT)
            self.link.poll()
            steps.append(step)
        self.last = steps[-1]
        return steps


RoverMaker = Callable[..., Rover]  # rover_on's factory


@pytest.fixture
def rover_on(request: pytest.FixtureRequest) -> Iterator[RoverMaker]:
    """A factory: ``rover_on(slope_deg, yaw, brake_a, current_limit_a)`` gives a ``Rover`` at rest; its
    buses and links are closed after the test."""
    with ExitStack() as stack:

        def make(
            slope_deg: float, yaw: float = 0.0, brake_a: float = 0.0, current_limit_a: float = 10.0
        ) -> Rover:
            companion, sim = stack.enter_context(virtual_bus_pair(request.node.name))
            clock = SimClock()
            link = CanLink(companion, make_codec(), clock, MemorySink())
            stack.callback(link.close)
            bank = SimVescBank(sim, make_codec(), clock, timeout_brake_current_a=brake_a)
            body = RoverDynamics(
                plane(slope_deg), PARAMS, x=50.0, y=50.0, yaw=yaw, motor_current_limit_a=current_limit_a
            )
            return Rover(body, bank, link, clock)

        yield make


def accel_over(steps: list[DynamicsStep], seconds: float) -> float:
    """Mean acceleration along the heading over the last ``seconds`` of ``steps`` (m/s^2)."""
    n = round(seconds / DT)
    return (steps[-1].speed_mps - steps[-1 - n].speed_mps) / (n * DT)


def test_six_released_wheels_slow_a_rover_on_the_level_by_rolling_resistance_only(
    rover_on: Callable[..., Rover],
) -> None:
    rover = rover_on(0.0)
    rover.run(2.0, [1.0] * 6)
    coasting = rover.run(1.5)  # silent: every controller times out at 0.5 s and lets go (brake 0)
    assert rover.bank.timeouts == 6
    assert accel_over(coasting, 0.8) == pytest.approx(-G * CRR, rel=1e-9)
    last = coasting[-1]
    assert last.speed_mps > 0.7  # still rolling: held, it would have stopped in 0.1 s
    # No slip, no drive force, no current; the wheels turn at the ground speed, and their controllers
    # report it (ERPM from the encoders of released motors), in the status frames too.
    assert last.slip == (0.0,) * 6 and last.traction_forces_n == (0.0,) * 6
    assert last.motor_currents_a == (0.0,) * 6 and last.duty == (0.0,) * 6
    assert last.wheel_speeds_mps == (last.speed_mps,) * 6
    assert rover.bank.wheel_speeds_mps() == pytest.approx([last.speed_mps] * 6, rel=1e-12)
    reported = [reading.speed_mps for reading in rover.link.readings()]
    assert reported == pytest.approx([last.speed_mps] * 6, abs=0.03)  # STATUS at 50 Hz, a step apart


@pytest.mark.parametrize("brake_a", [0.0, 1.0])
def test_a_rover_whose_controllers_time_out_on_a_slope_rolls_down_at_the_closed_form(
    rover_on: RoverMaker, brake_a: float
) -> None:
    slope = math.radians(20.0)
    assert math.tan(slope) > CRR
    rover = rover_on(20.0, yaw=math.pi, brake_a=brake_a)  # facing downhill
    held = rover.run(0.3, [0.0] * 6)
    assert abs(held[-1].speed_mps) < 0.01  # held by its controllers' speed loops
    rolling = rover.run(2.5)
    brake = 6.0 * brake_a * NEWTONS_PER_AMP / PARAMS.mass_kg
    expected = G * (math.sin(slope) - CRR * math.cos(slope)) - brake
    assert accel_over(rolling, 1.0) == pytest.approx(expected, rel=1e-9)
    # Each wheel's force is its brake's, against its forward turning, and no more.
    forces = rolling[-1].traction_forces_n
    assert forces == pytest.approx([-brake_a * NEWTONS_PER_AMP] * 6, rel=1e-9, abs=1e-12)


def test_a_brake_acts_against_the_wheels_turning_whichever_way_they_turn(rover_on: RoverMaker) -> None:
    """Driving up 15 deg when the link drops: the brake (1 A a wheel, less than gravity) slows the wheels
    turning forward until they stop, then holds against them turning backward as the rover rolls back."""
    slope = math.radians(15.0)
    brake = 6.0 * 1.0 * NEWTONS_PER_AMP / PARAMS.mass_kg
    assert brake < G * math.sin(slope)
    rover = rover_on(15.0, yaw=0.0, brake_a=1.0)  # facing uphill
    rover.run(1.0, [1.0] * 6)
    steps = rover.run(3.0)
    accels = [(b.speed_mps - a.speed_mps) / DT for a, b in itertools.pairwise(steps)]
    # Past the rolling resistance's fade (0.05 m/s) either way; the last going up is below 0.17 m/s, where
    # a brake aiming at 0 within the drive's 0.1 s would push forward against gravity (g sin 15 x 0.1 s).
    up = [a for a, s in zip(accels, steps[1:], strict=True) if s.speed_mps > 0.06]
    down = [a for a, s in zip(accels, steps[1:], strict=True) if s.speed_mps < -0.06]
    assert up and down
    assert up[-1] == pytest.approx(-G * (math.sin(slope) + CRR * math.cos(slope)) - brake, rel=1e-9)
    assert down[-1] == pytest.approx(-G * (math.sin(slope) - CRR * math.cos(slope)) + brake, rel=1e-9)


def test_a_braked_released_wheel_never_pulls_its_driving_side_forward() -> None:
    """One controller timed out (its frames lost) while the others drive: its brake acts only against its
    wheel's forward turning, so it gives no forward pull (it shares the side's force: 0 while the side
    drives; a released wheel's brake dragging a driving side is not modelled)."""
    body = RoverDynamics(plane(10.0), PARAMS, x=50.0, y=50.0, yaw=0.0)  # uphill: the side pulls forward
    for _ in range(50):
        body.step(DT, [1.0] * 6, PACK_V)
    one_released = (DRIVEN, 5.0, DRIVEN, DRIVEN, DRIVEN, DRIVEN) + (1.0,) * 6
    steps = [body.step(DT, [1.0] * 6, PACK_V, (), one_released) for _ in range(200)]
    assert steps[-1].speed_mps > 0.5
    assert all(step.traction_forces_n[1] <= 0.0 for step in steps)
    assert all(step.traction_forces_n[0] > 10.0 for step in steps[50:])


def test_a_brake_current_holding_more_than_gravity_keeps_the_rover_where_it_stopped(
    rover_on: Callable[..., Rover],
) -> None:
    slope = math.radians(20.0)
    # 3 A a wheel holds 229 N against the 151 N gravity pulls the 45 kg rover down 20 deg with.
    assert PARAMS.mass_kg * G * math.sin(slope) < 6.0 * 3.0 * NEWTONS_PER_AMP
    rover = rover_on(20.0, yaw=math.pi, brake_a=3.0)
    rover.run(0.3, [0.0] * 6)
    held = rover.run(2.5)
    assert rover.bank.timeouts == 6
    assert max(abs(step.speed_mps) for step in held) < 1e-3
    assert abs(held[-1].x - held[0].x) < 1e-3


def test_the_default_timeout_brake_holds_the_rover_and_stops_a_rolling_one(
    rover_on: Callable[..., Rover],
) -> None:
    rover = rover_on(20.0, yaw=math.pi, brake_a=DEFAULT_TIMEOUT_BRAKE_CURRENT_A)
    rover.run(1.0, [1.0] * 6)
    stopping = rover.run(3.0)
    assert stopping[-1].speed_mps == pytest.approx(0.0, abs=1e-3)


def test_a_rebooting_controller_lets_its_wheel_roll_with_the_ground() -> None:
    run = run_world(
        '[[faults]]\ntarget = "vesc"\nkind = "off"\nstart_s = 1.0\nduration_s = 1.0\ncontroller = 2\n'
    )
    during = run.on("truth/wheels", 1.2, 2.0)
    assert during
    for message in during:
        wheels = message["wheels"]
        assert wheels[2]["current_a"] == 0.0 and wheels[2]["slip"] == pytest.approx(0.0, abs=1e-9)
        # Its neighbours drive, slipping ahead of the ground; it turns slower than they do.
        assert (
            wheels[1]["current_a"] > 0.0 and wheels[2]["surface_speed_mps"] < wheels[1]["surface_speed_mps"]
        )
        assert wheels[2]["surface_speed_mps"] > 0.3  # rolling, not braked to 0 as before


def test_below_the_minimum_input_voltage_the_motors_let_go_until_it_is_back(
    rover_on: Callable[..., Rover],
) -> None:
    supply = SupplyLimits()
    rover = rover_on(0.0)
    rover.voltage_v = supply.min_input_voltage_v - 0.5
    rover.run(0.2, [1.0] * 6)  # the first step's controls are from the pack voltage given at the start
    faulted = rover.run(1.0, [1.0] * 6)
    assert rover.bank.under_voltage and rover.bank.under_voltage_faults == 1
    assert all(step.traction_forces_n == (0.0,) * 6 for step in faulted)
    assert max(abs(step.speed_mps) for step in faulted) == 0.0
    # The status frames keep coming (no STATUS field carries the fault code): six wheels, fresh.
    assert len(rover.link.readings()) == 6
    rover.voltage_v = PACK_V
    driving = rover.run(1.0, [1.0] * 6)
    assert not rover.bank.under_voltage
    assert driving[-1].speed_mps > 0.9


def test_the_battery_cut_off_ramps_the_current_limit_linearly_to_zero(rover_on: RoverMaker) -> None:
    supply = SupplyLimits()
    start, end = supply.battery_cut_start_v, supply.battery_cut_end_v
    assert supply.current_limit_fraction(0.5 * (start + end)) == pytest.approx(0.5, rel=1e-12)
    assert supply.current_limit_fraction(start) == 1.0 and supply.current_limit_fraction(end) == 0.0
    assert supply.current_limit_fraction(end + 0.25 * (start - end)) == pytest.approx(0.25, rel=1e-12)
    assert supply.current_limit_fraction(math.nan) == 0.0
    # In the physics: from rest to 1.5 m/s the motors pull at their current limit; a quarter of the way up
    # the ramp they may use a quarter of it (10 A -> 2.5 A), and do.
    peaks = []
    for voltage in (PACK_V, end + 0.25 * (start - end)):
        rover = rover_on(0.0)
        rover.voltage_v = voltage
        steps = rover.run(0.5, [1.5] * 6)
        assert rover.bank.wheel_controls()[:6] == (DRIVEN,) * 6
        peaks.append(max(max(step.motor_currents_a) for step in steps))
    assert peaks[0] > 5.0
    assert peaks[1] == pytest.approx(0.25 * 10.0, rel=1e-9)


@pytest.mark.parametrize(
    "limits",
    [
        {"battery_cut_start_v": 18.0, "battery_cut_end_v": 20.0},
        {"min_input_voltage_v": 19.0},
        {"battery_cut_end_v": math.nan},
    ],
)
def test_supply_limits_that_cannot_be_are_refused_by_name(limits: dict[str, float]) -> None:
    with pytest.raises(VescLimitsError, match="supply limits"):
        SupplyLimits(**limits)


def test_a_negative_timeout_brake_current_is_refused_by_name() -> None:
    clock = SimClock()
    with (
        virtual_bus_pair("brake") as (_, sim),
        pytest.raises(VescLimitsError, match="timeout_brake_current_a"),
    ):
        SimVescBank(sim, make_codec(), clock, timeout_brake_current_a=-1.0)


def test_a_wheel_its_current_limit_held_rolls_free_once_released(rover_on: RoverMaker) -> None:
    """Stalled on 15 deg at a 1.5 A limit (tests/hil/test_motor_current_limit.py: the wheels held nearly
    still, at the curve's slip), then the link falls silent: released (brake 0), the wheels no longer held
    roll back with the ground at the closed form, and the controllers report that rolling speed, not the
    stall's held one."""
    rover = rover_on(15.0, brake_a=0.0, current_limit_a=1.5)  # facing uphill
    stalled = rover.run(3.0, [1.0] * 6)
    assert abs(stalled[-1].speed_mps) < 0.01
    assert max(abs(r.speed_mps) for r in rover.link.readings()) < 0.01
    rolling = rover.run(1.5)
    slope = math.radians(15.0)
    assert accel_over(rolling, 0.5) == pytest.approx(-G * (math.sin(slope) - CRR * math.cos(slope)), rel=1e-9)
    assert rolling[-1].held_speeds_mps == ((-math.inf,) * 6, (math.inf,) * 6)
    speed = rolling[-1].speed_mps
    assert speed < -0.5
    erpm_step = 1.0 / make_codec().profile.erpm_per_mps
    assert [r.speed_mps for r in rover.link.readings()] == pytest.approx([speed] * 6, abs=0.02 + erpm_step)
