"""Battery energy, moving obstacles, simulated perception, the lockstep CAN bus, success criteria."""

from __future__ import annotations

import can
import numpy as np
import pytest

from firmware_bridge.vesc import VescCodec
from hil.battery import Battery
from hil.lockstep import lockstep_wires
from hil.lockstep_bus import lockstep_bus_pair
from hil.moving_obstacles import MovingObstacle
from hil.perception_sim import PerceptionSim
from hil.scenario import Obstacle
from hil.world import SimWorld
from logs.clock import SimClock, to_ns
from logs.settings import ConfigError, parse_toml
from logs.sink import MemorySink
from navigator.config import rover_config_from_table
from tests.hil.world_harness import run_world, scenario_with


def test_energy_is_the_integral_of_voltage_times_current():
    battery = Battery()
    currents = np.abs(np.sin(np.linspace(0.0, 20.0, 2000))) * 30.0
    integral_j = 0.0
    for current in currents:
        volts = battery.draw(float(current), 0.01)
        integral_j += volts * current * 0.01
    assert battery.energy_wh == pytest.approx(integral_j / 3600.0, rel=1e-12)
    assert battery.voltage_v < battery.params.full_voltage_v  # charge used and sag under load


def test_a_charging_current_gives_charge_and_energy_back_and_lifts_the_terminal_voltage():
    battery = Battery()
    battery.draw(10.0, 360.0)  # 1 Ah out
    resting = battery.open_circuit_voltage()
    used_wh = battery.energy_wh
    volts = battery.draw(-5.0, 360.0)  # 0.5 Ah back
    assert battery.charge_used_ah == pytest.approx(0.5, rel=1e-12)
    assert volts == pytest.approx(resting + 5.0 * battery.params.internal_resistance_ohm, rel=1e-12)
    assert battery.energy_wh == pytest.approx(used_wh - volts * 5.0 * 360.0 / 3600.0, rel=1e-12)


def test_charge_returned_to_a_full_pack_reads_full():
    battery = Battery()
    battery.draw(-2.0, 36.0)
    assert battery.state_of_charge == 1.0
    assert battery.open_circuit_voltage() == battery.params.full_voltage_v
    volts = battery.draw(0.0, 1.0)
    assert volts == battery.params.full_voltage_v


def test_a_current_that_is_not_a_number_reads_zero():
    battery = Battery()
    assert battery.draw(float("nan"), 1.0) == battery.params.full_voltage_v
    assert battery.charge_used_ah == 0.0 and battery.energy_wh == 0.0


def test_moving_obstacle_ping_pongs_along_its_waypoints():
    mover = MovingObstacle("walker", 0.5, ((0.0, 0.0), (4.0, 0.0), (4.0, 3.0)), speed_mps=1.0, start_s=1.0)
    assert mover.state_at(0.5) == (0.0, 0.0, 0.0, 0.0)
    assert mover.state_at(3.0) == pytest.approx((2.0, 0.0, 1.0, 0.0))
    assert mover.state_at(6.5) == pytest.approx((4.0, 1.5, 0.0, 1.0))
    assert mover.state_at(9.5) == pytest.approx((4.0, 1.5, 0.0, -1.0))  # on its way back
    assert mover.state_at(14.5) == pytest.approx((0.5, 0.0, -1.0, 0.0))


def test_perception_reports_only_obstacles_in_range_at_its_rate():
    clock = SimClock()
    rover = [0.0, 0.0]
    perception = PerceptionSim(
        clock,
        lambda: (rover[0], rover[1]),
        [Obstacle("near", 3.0, 0.0, 0.5), Obstacle("far", 20.0, 0.0, 0.5)],
        [MovingObstacle("walker", 0.4, ((5.0, -5.0), (5.0, 5.0)), speed_mps=1.0)],
        np.random.default_rng(0),
        range_m=6.0,
        rate_hz=10.0,
    )
    clock.advance(to_ns(2.0))  # the walker has walked from (5, -5) to (5, -3)
    first = perception.poll()
    assert {o.obstacle_id for o in first} == {"near", "walker"}
    walker = next(o for o in first if o.obstacle_id == "walker")
    assert walker.moving and (walker.vx, walker.vy) == pytest.approx((0.0, 1.0))
    assert perception.poll() == []  # nothing new before the next period
    clock.advance(to_ns(0.1))
    rover[0] = 16.0
    assert {o.obstacle_id for o in perception.poll()} == {"far"}


def test_perception_noise_is_one_normal_pair_per_candidate_in_order_seen_or_not():
    """A poll's noise is drawn in one call: the same numbers as a pair per candidate in candidate order
    (static, then moving), the pairs of obstacles out of range drawn and dropped."""
    clock = SimClock()
    static = [
        Obstacle("near", 3.0, 0.0, 0.5),
        Obstacle("far", 20.0, 0.0, 0.5),
        Obstacle("close", 0.0, 2.0, 0.3),
    ]
    moving = [MovingObstacle("walker", 0.4, ((5.0, -5.0), (5.0, 5.0)), speed_mps=1.0)]
    perception = PerceptionSim(
        clock, lambda: (0.0, 0.0), static, moving, np.random.default_rng(7), range_m=6.0, noise_m=0.25
    )
    expected_rng = np.random.default_rng(7)
    clock.advance(to_ns(2.0))
    for _ in range(3):
        seen = {o.obstacle_id: (o.x, o.y) for o in perception.poll()}
        pairs = [expected_rng.normal(0.0, 1.0, 2) * 0.25 for _ in range(len(static) + len(moving))]
        assert set(seen) == {"near", "close", "walker"}
        for obstacle, noise in zip(static, pairs, strict=False):
            if obstacle.id != "far":
                assert seen[obstacle.id] == (obstacle.x + float(noise[0]), obstacle.y + float(noise[1]))
        clock.advance(to_ns(0.1))


def test_moving_obstacle_hitting_the_rover_is_a_recorded_collision():
    extra = """
[[moving_obstacles]]
id = "cart"
radius_m = 0.4
speed_mps = 1.0
waypoints = [[2.0, 5.0], [2.0, 0.5]]
"""
    run = run_world(extra, seconds=4.0, speed_mps=0.0)
    contacts = run.on("truth/contacts")
    assert [(c["kind"], c["obstacle_id"]) for c in contacts] == [("collision", "cart")]


def test_bad_moving_obstacle_names_the_key():
    with pytest.raises(ConfigError, match=r"moving_obstacles\[0\]\.waypoints"):
        scenario_with("[[moving_obstacles]]\nradius_m = 0.5\nspeed_mps = 1.0\nwaypoints = [[1.0, 1.0]]\n")


def test_lockstep_bus_delivers_in_order_and_filters():
    clock = SimClock()
    rover, sim = lockstep_bus_pair("test", clock)
    try:
        for i in range(3):
            rover.send(can.Message(arbitration_id=0x100 + i, data=bytes([i]), is_extended_id=True))
        received = [sim.recv(timeout=0) for _ in range(4)]
        assert [m.arbitration_id for m in received[:3]] == [0x100, 0x101, 0x102]
        assert received[3] is None
        assert rover.recv(timeout=0) is None  # nobody hears its own frames
        sim.set_filters([{"can_id": 0x101, "can_mask": 0x7FF, "extended": True}])
        for i in range(3):
            rover.send(can.Message(arbitration_id=0x100 + i, is_extended_id=True))
        # python-can semantics: recv(timeout=0) returns None for a frame the filters reject.
        assert [getattr(sim.recv(timeout=0), "arbitration_id", None) for _ in range(3)] == [None, 0x101, None]
    finally:
        rover.shutdown()
        sim.shutdown()
    with pytest.raises(can.CanOperationError):
        rover.send(can.Message(arbitration_id=1))


@pytest.mark.parametrize(("forward_m", "seen"), [(0.0, set()), (3.0, {"rock"})])
def test_object_perception_measures_its_range_from_the_sensors_mount(forward_m: float, seen: set) -> None:
    # small_rocky's rover starts at (2, 2) facing 20 deg; its rock, radius 0.8 at (6.5, 4.5), is 4.35 m from
    # the centre to its edge and 1.43 m from a point 3 m ahead: outside a 2 m range, then inside it.
    extra = f"""
[sensors]
perception_range_m = 2.0
perception_mount_forward_m = {forward_m}
"""
    scenario = scenario_with(extra)
    assert {o.id for o in scenario.obstacles} == {"rock"}
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    clock = SimClock()
    with lockstep_wires(config.can, clock=clock) as wires:
        codec = VescCodec.for_profile(config.vesc)
        world = SimWorld(
            scenario, config.vehicle, codec, clock, wires.sim_bus, wires.sim_mavlink, MemorySink(), 1
        )
        with world:
            assert {o.obstacle_id for o in world.perception.poll()} == seen
