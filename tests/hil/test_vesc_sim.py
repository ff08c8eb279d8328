import can
import pytest

from firmware_bridge.can_link import CanLink
from hil.vesc_sim import SimVescBank
from logs.clock import SimClock, to_ns
from logs.sink import MemorySink
from logs.topics import CAN_FRAMES, WHEELS_STATUS
from tests.firmware_bridge.virtual_can import BUS_KINDS, TEST_PROFILE, bus_pair, make_codec, virtual_bus_pair

DT_S = 0.01


@pytest.fixture(params=BUS_KINDS)
def buses(request):
    """Each test on a virtual bus and on the lockstep one, whose link and controllers move frames in
    batches (BatchBus): the same behaviour either way."""
    with bus_pair(request.param, request.node.name) as pair:
        yield pair


def run(link, sim, clock, seconds, speeds=None):
    """Lockstep: command (if given), simulate, read status; 100 Hz."""
    for _ in range(round(seconds / DT_S)):
        if speeds is not None:
            link.send_wheel_speeds(speeds)
        sim.poll()
        clock.advance(to_ns(DT_S))
        sim.step(DT_S)
        link.poll()


def make_pair(buses, clock, sink, **sim_kwargs):
    companion_bus, sim_bus = buses
    link = CanLink(companion_bus, make_codec(), clock, sink)
    sim = SimVescBank(sim_bus, make_codec(), clock, **sim_kwargs)
    return link, sim


def test_input_current_is_what_the_motor_takes_from_the_pack(buses):
    # Driving forward and in reverse both take power (I x duty > 0); a braking motor (current against
    # its duty) generates and gives it back either way, down to the controller's floor (2 A by default:
    # -8 A at duty 0.3 returns 2 A, not 2.4).
    clock, sink = SimClock(), MemorySink()
    link, sim = make_pair(buses, clock, sink)
    sim.set_electrical([4.0, -4.0, -3.0, 3.0, -8.0, 2.0], 24.0, [0.5, -0.5, 0.4, -0.4, 0.3, 0.0])
    run(link, sim, clock, 0.3, [0.0] * 6)
    readings = link.readings()
    assert [r.duty for r in readings] == pytest.approx([0.5, -0.5, 0.4, -0.4, 0.3, 0.0], abs=1e-3)
    assert [r.input_current_a for r in readings] == pytest.approx([2.0, 2.0, -1.2, -1.2, -2.0, 0.0], abs=0.1)


def test_a_regeneration_floor_of_zero_returns_nothing(buses):
    clock, sink = SimClock(), MemorySink()
    link, sim = make_pair(buses, clock, sink, regen_current_limit_a=0.0)
    sim.set_electrical([4.0, -3.0, 0.0, 0.0, 0.0, 0.0], 24.0, [0.5, 0.4, 0.0, 0.0, 0.0, 0.0])
    run(link, sim, clock, 0.3, [0.0] * 6)
    assert [r.input_current_a for r in link.readings()][:2] == pytest.approx([2.0, 0.0], abs=0.1)


def test_commands_reach_the_motors_and_status_comes_back(buses):
    clock, sink = SimClock(), MemorySink()
    link, sim = make_pair(buses, clock, sink)
    speeds = [0.5, 0.5, 0.5, -0.3, -0.3, -0.3]
    expected = [round(TEST_PROFILE.erpm_from_speed(s)) for s in speeds]
    sim.set_electrical([2.0] * 6, 25.2, [e / 30_000 for e in expected])  # duty as the physics gives it
    run(link, sim, clock, 1.0, speeds)
    assert sim.targets_erpm() == expected
    assert sim.wheel_speeds_mps() == pytest.approx(speeds, abs=1e-3)
    readings = link.readings()
    assert [r.controller_id for r in readings] == [1, 2, 3, 4, 5, 6]
    assert [r.speed_mps for r in readings] == pytest.approx(speeds, abs=2e-3)
    assert readings[0].motor_current_a == pytest.approx(2.0)
    assert readings[0].input_voltage_v == pytest.approx(25.2)
    assert readings[0].duty == pytest.approx(expected[0] / 30_000, abs=2e-3)
    assert readings[0].input_current_a == pytest.approx(2.0 * expected[0] / 30_000, abs=0.1)
    # roughly 0.5 m/s for ~1 s, less the spin-up: tachometer counts electrical revolutions
    assert readings[0].tachometer == pytest.approx(TEST_PROFILE.erpm_from_speed(0.5) / 60 * 0.95, rel=0.05)
    assert readings[3].tachometer < 0
    statuses = sink.on(WHEELS_STATUS)
    assert 45 <= len(statuses) <= 55  # STATUS at 50 Hz
    assert statuses[-1]["wheels"][0]["speed_mps"] == pytest.approx(0.5, abs=2e-3)
    errors = {k: v for k, v in link.counters.as_dict().items() if k not in ("tx", "rx")}
    assert errors == dict.fromkeys(errors, 0)
    assert sim.bad_frames == 0 and sim.ignored_frames == 0
    # 6 STATUS at 50 Hz + 12 slow at 10 Hz for 1 s, all recorded as rx
    rx = [m for m in sink.on(CAN_FRAMES) if m["direction"] == "rx"]
    assert len(rx) == link.counters.rx == pytest.approx(6 * 50 + 12 * 10, abs=18)


def test_command_timeout_releases_the_motors(buses):
    """Past the timeout the controllers let go (target 0, released): with no physics turning the wheels
    (``set_rolling_speeds``), their encoders read the 0 m/s the bank was given (a rolling rover:
    tests/hil/test_released_wheels.py)."""
    clock, sink = SimClock(), MemorySink()
    link, sim = make_pair(buses, clock, sink, command_timeout_s=0.5)
    run(link, sim, clock, 0.5, [1.0] * 6)
    assert sim.wheel_speeds_mps() == pytest.approx([1.0] * 6, abs=0.01)
    run(link, sim, clock, 0.45)  # silence, but within the timeout: still driving
    assert sim.targets_erpm()[0] > 0
    assert sim.timeouts == 0
    run(link, sim, clock, 0.5)  # past the timeout
    assert sim.targets_erpm() == [0.0] * 6
    assert sim.timeouts == 6
    assert max(abs(s) for s in sim.wheel_speeds_mps()) < 0.01
    assert max(abs(r.speed_mps) for r in link.readings()) < 0.01


def test_frames_for_other_controllers_are_ignored_and_bad_frames_counted(buses):
    companion_bus, sim_bus = buses
    clock = SimClock()
    sim = SimVescBank(sim_bus, make_codec(), clock)
    companion_bus.send(can.Message(arbitration_id=(3 << 8) | 77, data=bytes.fromhex("00001000")))
    companion_bus.send(can.Message(arbitration_id=(3 << 8) | 1, data=bytes.fromhex("0000")))
    companion_bus.send(can.Message(arbitration_id=(3 << 8) | 2, data=bytes.fromhex("00001000")))
    companion_bus.send(can.Message(arbitration_id=(2 << 8) | 3, data=bytes.fromhex("00000000")))
    assert sim.poll() == 4
    assert sim.ignored_frames == 1
    assert sim.bad_frames == 1
    assert sim.targets_erpm() == [0.0, 4096.0, 0.0, 0.0, 0.0, 0.0]
    assert sim.commands_applied == 2


def test_lockstep_run_is_deterministic(request):
    def one_run(label):
        with virtual_bus_pair(label) as pair:
            clock, sink = SimClock(), MemorySink()
            link, sim = make_pair(pair, clock, sink)
            run(link, sim, clock, 0.3, [0.2, 0.4, 0.6, -0.2, -0.4, -0.6])
            return sink.records

    first, second = one_run(request.node.name + "a"), one_run(request.node.name + "b")
    assert first == second
    assert len(first) > 100


def test_loads_from_the_physics_are_clamped_into_the_status_fields_as_max_min_clamps_them(buses):
    """The loads' clamps (set_electrical's, applied when a status is next due) give what
    max(-limit, min(limit, x)) gives, edges included: a current beyond +-3000 A is the limit and a
    non-finite one 0; a duty beyond +-1 is +-1, NaN 1.0 (as before)."""
    import math

    import numpy as np

    _, sim = make_pair(buses, SimClock(), MemorySink())
    nan, inf = float("nan"), float("inf")
    currents = [nan, inf, -inf, 5000.0, -5000.0, -0.0]
    duties = [nan, inf, -inf, 2.0, -2.0, -0.0]
    for convert in (list, np.array):
        sim.set_electrical(convert(currents), 24.0, convert(duties))
        sim._take_loads()  # what the next status period does first
        want_currents = [max(-3000.0, min(3000.0, c)) if math.isfinite(c) else 0.0 for c in convert(currents)]
        want_duties = [max(-1.0, min(1.0, d)) for d in convert(duties)]
        assert [(float(c), math.copysign(1.0, c)) for c in sim._motor_current_a] == [
            (float(c), math.copysign(1.0, c)) for c in want_currents
        ]
        assert [(float(d), math.copysign(1.0, d)) for d in sim._duty_cycle] == [
            (float(d), math.copysign(1.0, d)) for d in want_duties
        ]
    sim.set_electrical([1.5, -2.5, 3000.0, -3000.0, 0.25, 0.0], 24.0, [0.5, -0.5, 1.0, -1.0, 0.0, 0.999])
    sim._take_loads()
    assert sim._motor_current_a == [1.5, -2.5, 3000.0, -3000.0, 0.25, 0.0]
    assert sim._duty_cycle == [0.5, -0.5, 1.0, -1.0, 0.0, 0.999]


def test_set_rpm_beyond_the_motors_limit_is_clamped_to_it(buses):
    clock = SimClock()
    link, sim = make_pair(buses, clock, MemorySink(), max_erpm=1000.0)
    erpm_per_mps = TEST_PROFILE.erpm_per_mps
    link.send_wheel_speeds([e / erpm_per_mps for e in (5000.0, -5000.0, 1000.0, -1000.0, 999.0, 0.0)])
    sim.poll()
    assert sim.targets_erpm() == [1000.0, -1000.0, 1000.0, -1000.0, 999.0, 0.0]
