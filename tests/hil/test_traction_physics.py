"""The wheel-ground laws (hil.traction) in the body (hil.dynamics) against closed forms and physical sense:
traction-slip curve, skid-steer scrub, sinkage resistance, motor current limit."""

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from firmware_bridge.can_link import CanLink
from hil.dynamics import RoverDynamics
from hil.traction import SCRUB_SPEED_EPS_MPS, SLIP_SIGN_EPS_MPS, slip_for_ratio, traction_ratio
from hil.vesc_sim import SimVescBank
from logs.clock import SimClock, to_ns
from logs.sink import MemorySink
from navigator.errors import TerrainError
from navigator.terrain import TerrainMap
from navigator.terrain_classes import FIRM, MUDDY, ROCKY, SANDY, TERRAIN_CLASSES
from navigator.vehicle import G, VehicleParams
from tests.firmware_bridge.virtual_can import make_codec, virtual_bus_pair

PARAMS = VehicleParams()
DT = 0.01
VOLTS = 24.0


def plane(grade_x=0.0, class_id=FIRM, size=(80, 80), res=0.25):
    xs = (np.arange(size[1]) + 0.5) * res
    elevation = np.broadcast_to(grade_x * xs[np.newaxis, :], size).copy()
    return TerrainMap(elevation, np.full(size, class_id, np.uint8), np.zeros(size, bool), res)


def settle(body, wheels, seconds=3.0):
    steps = [body.step(DT, wheels, VOLTS) for _ in range(round(seconds / DT))]
    return steps[-1]


@pytest.mark.parametrize("class_id", sorted(TERRAIN_CLASSES))
def test_traction_curve_rises_with_slip_and_saturates_at_mu(class_id):
    c = TERRAIN_CLASSES[class_id]
    slips = np.linspace(0.0, 1.0, 41)
    ratios = [traction_ratio(s, c.friction_mu, c.slip_constant) for s in slips]
    assert ratios[0] == 0.0
    assert np.all(np.diff(ratios) > 0.0)
    assert ratios[-1] == pytest.approx(c.friction_mu, rel=1e-12)
    assert traction_ratio(-slips[12], c.friction_mu, c.slip_constant) == -ratios[12]
    for s, ratio in zip(slips[1:-1], ratios[1:-1], strict=True):
        assert slip_for_ratio(ratio, c.friction_mu, c.slip_constant) == pytest.approx(s, abs=1e-9)
    assert slip_for_ratio(c.friction_mu, c.friction_mu, c.slip_constant) == 1.0
    assert slip_for_ratio(-2.0 * c.friction_mu, c.friction_mu, c.slip_constant) == -1.0


@pytest.mark.parametrize("class_id", [FIRM, SANDY])
def test_climbing_slip_follows_the_curve_and_saturates_past_the_climb_limit(class_id):
    c = TERRAIN_CLASSES[class_id]
    slips = []
    for degrees in (0.0, 4.0, 8.0):
        theta = math.radians(degrees)
        body = RoverDynamics(plane(math.tan(theta), class_id), PARAMS, x=10.0, y=10.0, yaw=0.0)
        last = settle(body, [0.8] * 6)
        for force, load, slip in zip(last.traction_forces_n, last.normal_forces_n, last.slip, strict=True):
            assert slip == pytest.approx(
                slip_for_ratio(force / load, c.friction_mu, c.slip_constant), rel=1e-9
            )
        # Every wheel slips alike (equal loads share the force by load), and the ground lags the tyre by it.
        assert max(last.slip) - min(last.slip) < 1e-9
        assert body.speed == pytest.approx(0.8 * (1.0 - last.slip[0]), rel=1e-5)
        slips.append(last.slip[0])
    assert 0.0 < slips[0] < slips[1] < slips[2] < 1.0
    # Past tan(theta) = mu - crr the wheels spin (slip 1) and pull exactly mu N.
    theta = math.atan(c.friction_mu - c.rolling_resistance) + 0.05
    body = RoverDynamics(plane(math.tan(theta), class_id), PARAMS, x=10.0, y=10.0, yaw=0.0)
    last = settle(body, [0.8] * 6, 1.0)
    assert body.speed < 0.0 and min(last.slip) == 1.0
    assert sum(last.traction_forces_n) == pytest.approx(c.friction_mu * sum(last.normal_forces_n), rel=1e-9)


# The motor model of RoverDynamics' defaults: wheel radius from the params, gear 20, k_t 0.07 N m/A, 0.1 ohm.
GEAR, K_T, WINDING_OHM = 20.0, 0.07, 0.1


def test_descending_slower_than_gravity_would_go_the_wheels_brake_at_the_curves_slip():
    """Downhill with the wheels turning slower than the rover would roll: every wheel brakes with the curve's
    force for its (negative) slip, the rover runs ahead of its tyres by that slip, the motors generate and
    return to the pack the braking power less the windings' loss, and the energy is the integral of V I."""
    firm = TERRAIN_CLASSES[FIRM]
    theta = math.radians(20.0)
    wheel = 0.6
    body = RoverDynamics(plane(-math.tan(theta)), PARAMS, x=3.0, y=10.0, yaw=0.0)  # facing downhill
    steps = [body.step(DT, [wheel] * 6, VOLTS) for _ in range(300)]
    last = steps[-1]
    # Steady: the wheels hold back gravity less rolling resistance, each in proportion to its load.
    ratio = -(math.tan(theta) - firm.rolling_resistance)
    slip = slip_for_ratio(ratio, firm.friction_mu, firm.slip_constant)
    assert slip < 0.0
    assert sum(last.traction_forces_n) == pytest.approx(
        -PARAMS.mass_kg * G * (math.sin(theta) - firm.rolling_resistance * math.cos(theta)), rel=1e-6
    )
    for force, load, wheel_slip in zip(last.traction_forces_n, last.normal_forces_n, last.slip, strict=True):
        assert force / load == pytest.approx(ratio, rel=1e-6)
        assert wheel_slip == pytest.approx(slip, rel=1e-6)
    assert body.speed == pytest.approx(wheel / (1.0 + slip), rel=1e-6)  # ground ahead of the tyre
    assert body.speed > wheel
    # Braking current: the force's sign; the motor turns forward, so it generates and gives it back: the
    # pack takes the braking power at the tyres, sum F u, less the windings' I^2 R (within the default
    # controllers' regeneration floor: ~0.3 A each here).
    copper_w = 0.0
    for force, current, duty in zip(last.traction_forces_n, last.motor_currents_a, last.duty, strict=True):
        assert current == pytest.approx(force * PARAMS.wheel_radius_m / (GEAR * K_T), rel=1e-12)
        assert current < 0.0 < duty
        back_emf = K_T * GEAR * wheel / PARAMS.wheel_radius_m
        assert back_emf * current + current**2 * WINDING_OHM < 0.0
        copper_w += current**2 * WINDING_OHM
    returned_w = sum(last.traction_forces_n) * wheel + copper_w
    assert returned_w < 0.0
    assert last.battery_current_a == pytest.approx(returned_w / VOLTS, rel=1e-9)
    assert last.energy_wh < steps[-100].energy_wh  # braking steadily charges the pack
    # Energy is the integral of V I over the whole run (the start drew a little while the wheels pulled).
    integral_wh = sum(s.battery_current_a * VOLTS * DT for s in steps) / 3600.0
    assert last.energy_wh == pytest.approx(integral_wh, rel=1e-12)


@pytest.mark.parametrize("limit_a", [0.0, 0.1])
def test_a_controllers_regeneration_floor_caps_what_the_pack_takes_not_the_braking(limit_a):
    """Past each controller's battery current floor (0: no regeneration) the pack takes the floor, six
    times over, and the braking force is what it was with room to spare."""
    theta, wheel = math.radians(20.0), 0.6

    def steady(**motor):
        body = RoverDynamics(plane(-math.tan(theta)), PARAMS, x=3.0, y=10.0, yaw=0.0, **motor)
        return [body.step(DT, [wheel] * 6, VOLTS) for _ in range(300)][-1]

    free, capped = steady(), steady(regen_current_limit_a=limit_a)
    assert free.battery_current_a < -6.0 * limit_a  # room to spare by default: the floor binds below
    assert capped.battery_current_a == pytest.approx(-6.0 * limit_a, abs=1e-12)
    assert capped.traction_forces_n == free.traction_forces_n


def test_a_regeneration_floor_that_is_not_a_number_is_refused():
    with pytest.raises(ValueError, match="regen_current_limit_a"):
        RoverDynamics(plane(), PARAMS, x=3.0, y=10.0, yaw=0.0, regen_current_limit_a=math.nan)
    with pytest.raises(ValueError, match="regen_current_limit_a"):
        RoverDynamics(plane(), PARAMS, x=3.0, y=10.0, yaw=0.0, regen_current_limit_a=-1.0)


def wrong_way_pulls(body, commands, seconds):
    """Steps in which a wheel pulled against the sign of its slip at the start of the step:
    (wheel speed - ground speed under it, force)."""
    wrong = []
    for tick in range(round(seconds / DT)):
        wheels = commands(tick * DT)
        speed, yaw_rate = body.speed, body.yaw_rate
        step = body.step(DT, wheels, VOLTS)
        for i, force in enumerate(step.traction_forces_n):
            side = 1.0 if i >= 3 else -1.0
            sliding = wheels[i] - (speed + side * 0.5 * yaw_rate * PARAMS.effective_track_m)
            slower, faster = sliding < -SLIP_SIGN_EPS_MPS, sliding > SLIP_SIGN_EPS_MPS
            if (slower and force > 0.0) or (faster and force < 0.0):
                wrong.append((sliding, force))
            assert (step.motor_currents_a[i] > 0.0) == (force > 0.0)
    return wrong


@pytest.mark.parametrize(("class_id", "degrees", "wheel"), [(MUDDY, 22.0, 0.5), (SANDY, 26.0, 0.6)])
def test_on_a_slippery_descent_a_wheel_slower_than_the_ground_never_pulls_forward(class_id, degrees, wheel):
    """Starting from rest the rover overtakes its wheels on the way to the steady braking slip; from then
    on the wheels may only brake (the force was once clipped to the traction limits only, and pulled)."""
    body = RoverDynamics(
        plane(-math.tan(math.radians(degrees)), class_id, size=(80, 400)), PARAMS, x=3.0, y=10.0, yaw=0.0
    )
    assert wrong_way_pulls(body, lambda _t: [wheel] * 6, 4.0) == []
    last = body.step(DT, [wheel] * 6, VOLTS)
    assert all(f < 0.0 for f in last.traction_forces_n) and all(s < 0.0 for s in last.slip)
    assert body.speed > wheel


PROPERTY = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@PROPERTY
@given(
    class_id=st.sampled_from(sorted(TERRAIN_CLASSES)),
    degrees=st.floats(-30.0, 30.0),
    heading=st.floats(-math.pi, math.pi),
    first=st.tuples(st.floats(-1.5, 1.5), st.floats(-1.5, 1.5)),
    second=st.tuples(st.floats(-1.5, 1.5), st.floats(-1.5, 1.5)),
)
def test_no_wheel_ever_pulls_against_the_sign_of_its_slip(class_id, degrees, heading, first, second):
    """Any class, slope, heading and change of command: a wheel slower than the ground under it never pulls
    forward, one faster never brakes, and its motor current has the sign of its force."""
    body = RoverDynamics(
        plane(math.tan(math.radians(degrees)), class_id, size=(120, 120)), PARAMS, x=15.0, y=15.0, yaw=heading
    )

    def commands(t):
        left, right = first if t < 0.6 else second
        return [left] * 3 + [right] * 3

    assert wrong_way_pulls(body, commands, 1.2) == []


def steady_turn_slip(class_id, wheel_speed):
    """Slip s of a turn on the spot on level ground, from the laws: the wheels' pull mu(s) N balances the
    rolling resistance and the end axles' scrub, whose sideways share falls as the wheels slip."""
    c = TERRAIN_CLASSES[class_id]
    lever = PARAMS.wheelbase_m / 2.0
    lo, hi = 0.0, 1.0
    for _ in range(60):
        s = 0.5 * (lo + hi)
        yaw_rate = 2.0 * wheel_speed * (1.0 - s) / PARAMS.effective_track_m
        sideways = yaw_rate * lever + SCRUB_SPEED_EPS_MPS
        share = sideways / math.hypot(sideways, wheel_speed * s)
        # Moment balance: 6 wheels x F x track/2 = mu_t x 4 end wheels x N x lever x share (+ rolling).
        needed = 2.0 / 3.0 * c.lateral_resistance * share * PARAMS.wheelbase_m / PARAMS.track_m
        needed += c.rolling_resistance
        if traction_ratio(s, c.friction_mu, c.slip_constant) > needed:
            hi = s
        else:
            lo = s
    return 0.5 * (lo + hi), needed


@pytest.mark.parametrize("class_id", [FIRM, ROCKY, SANDY, MUDDY])
def test_turn_on_the_spot_falls_short_of_the_wheel_speed_rate_by_the_scrub_slip(class_id):
    body = RoverDynamics(plane(class_id=class_id), PARAMS, x=10.0, y=10.0, yaw=0.0)
    last = settle(body, [-0.4] * 3 + [0.4] * 3, 4.0)
    slip, ratio = steady_turn_slip(class_id, 0.4)
    kinematic = 0.8 / PARAMS.effective_track_m
    assert body.yaw_rate == pytest.approx(kinematic * (1.0 - slip), rel=1e-4)
    assert body.speed == pytest.approx(0.0, abs=1e-9)
    wheel_load = PARAMS.mass_kg * G / 6.0
    assert last.traction_forces_n[3] == pytest.approx(ratio * wheel_load, rel=1e-3)
    assert last.traction_forces_n[0] == pytest.approx(-ratio * wheel_load, rel=1e-3)


def test_a_turn_on_sand_needs_more_torque_and_turns_slower_than_on_rock():
    results = {}
    for class_id in (ROCKY, SANDY):
        body = RoverDynamics(plane(class_id=class_id), PARAMS, x=10.0, y=10.0, yaw=0.0)
        last = settle(body, [-0.4] * 3 + [0.4] * 3, 4.0)
        results[class_id] = (sum(abs(i) for i in last.motor_currents_a), body.yaw_rate)
    assert results[SANDY][0] > 1.05 * results[ROCKY][0]
    assert results[SANDY][1] < 0.8 * results[ROCKY][1]


def test_a_gentle_arc_scrubs_less_than_a_tight_one():
    """Wong's lateral-resistance fit: the wider the turn, the less the end axles resist (and slip)."""
    slips = []
    for inner in (0.2, 0.6):  # outer side at 1.0 m/s
        body = RoverDynamics(plane(class_id=SANDY, size=(200, 200)), PARAMS, x=25.0, y=25.0, yaw=0.0)
        last = settle(body, [inner] * 3 + [1.0] * 3, 3.0)
        slips.append(last.slip[3])
    assert slips[0] > slips[1] > 0.0


@pytest.mark.parametrize(("class_id", "grows"), [(MUDDY, True), (SANDY, True), (ROCKY, False)])
def test_sinkage_resistance_grows_with_load_on_soft_ground_only(class_id, grows):
    c = TERRAIN_CLASSES[class_id]
    coefficients = []
    for mass in (45.0, 90.0):
        params = VehicleParams(mass_kg=mass)
        body = RoverDynamics(plane(class_id=class_id), params, x=10.0, y=10.0, yaw=0.0)
        last = settle(body, [0.5] * 6)
        coefficients.append(sum(last.traction_forces_n) / (mass * G))  # steady: pull = motion resistance
    # At the table's reference load (the 45 kg rover) the coefficient is the table's crr.
    assert coefficients[0] == pytest.approx(c.rolling_resistance, rel=1e-6)
    # Twice the load: Bekker's compaction part grows as load^(1 / (2n + 1)).
    expected = c.rolling_resistance + c.sinkage_resistance * (
        2.0 ** (1.0 / (2.0 * c.sinkage_exponent + 1.0)) - 1.0
    )
    assert coefficients[1] == pytest.approx(expected, rel=1e-6)
    assert (coefficients[1] > coefficients[0] * 1.1) is grows


def test_a_wheel_at_its_current_limit_gives_way_and_the_others_take_the_rest():
    theta = math.radians(15.0)
    free = RoverDynamics(plane(math.tan(theta)), PARAMS, x=10.0, y=10.0, yaw=0.0)
    needed = settle(free, [0.5] * 6)
    rear_current = needed.motor_currents_a[2]
    assert rear_current == max(needed.motor_currents_a)  # the rear carries most load uphill
    limit = 0.9 * rear_current
    body = RoverDynamics(plane(math.tan(theta)), PARAMS, x=10.0, y=10.0, yaw=0.0, motor_current_limit_a=limit)
    last = settle(body, [0.5] * 6)
    assert last.motor_currents_a[2] == pytest.approx(limit, rel=1e-12)
    assert max(last.motor_currents_a) <= limit * (1.0 + 1e-12)
    assert last.motor_currents_a[1] > needed.motor_currents_a[1]
    crr = TERRAIN_CLASSES[FIRM].rolling_resistance
    expected_drive = PARAMS.mass_kg * G * (math.sin(theta) + crr * math.cos(theta))
    assert sum(last.traction_forces_n) == pytest.approx(expected_drive, rel=1e-3)
    assert body.speed > 0.4


@pytest.fixture
def buses(request):
    with virtual_bus_pair(request.node.name) as pair:
        yield pair


def test_commanded_beyond_the_current_limit_the_rover_stalls_and_the_vesc_reports_the_limit(buses):
    """Through the simulated VESCs on a CAN bus: a 20 degree climb needs more than 1.5 A a wheel."""
    limit = 1.5
    theta = math.radians(20.0)
    body = RoverDynamics(plane(math.tan(theta)), PARAMS, x=10.0, y=10.0, yaw=0.0, motor_current_limit_a=limit)
    clock, sink = SimClock(), MemorySink()
    companion_bus, sim_bus = buses
    link = CanLink(companion_bus, make_codec(), clock, sink)
    vescs = SimVescBank(sim_bus, make_codec(), clock)
    reported = []
    for _ in range(200):
        link.send_wheel_speeds([0.8] * 6)
        vescs.poll()
        clock.advance(to_ns(DT))
        step = body.step(DT, vescs.wheel_speeds_mps(), VOLTS)
        vescs.set_electrical(step.motor_currents_a, VOLTS, step.duty)
        vescs.step(DT)
        link.poll()
        reported.extend(r.motor_current_a for r in link.readings())
    assert body.x < 10.0  # the wheels cannot pull it up: it rolls back
    assert max(step.motor_currents_a) == pytest.approx(limit)
    assert max(reported) == pytest.approx(limit, abs=0.05)  # STATUS carries 0.1 A resolution
    assert sum(step.traction_forces_n) < PARAMS.mass_kg * G * math.sin(theta)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"slip_constant": 0.0}, "slip_constant"),
        ({"sinkage_resistance": 0.5}, "sinkage_resistance"),
        ({"sinkage_exponent": -1.0}, "sinkage_exponent"),
        ({"lateral_resistance": -0.1}, "lateral_resistance"),
        ({"friction_mu": 0.0}, "friction_mu"),
    ],
)
def test_a_class_with_impossible_wheel_ground_parameters_is_a_terrain_error(changes, message):
    with pytest.raises(TerrainError, match=message):
        dataclasses.replace(TERRAIN_CLASSES[SANDY], **changes)
