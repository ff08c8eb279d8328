"""Through the whole simulated world: wheels braking downhill charge the battery (the motors generate and
their controllers return it, as VESCs do); what the controllers report as input current is what the pack
takes, and the pack's energy is still the integral of V I."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from firmware_bridge.can_link import CanLink
from firmware_bridge.vesc import VescCodec
from hil.lockstep import lockstep_wires
from hil.world import ELECTRONICS_CURRENT_A, SimWorld
from logs.clock import SimClock
from logs.settings import parse_toml
from logs.sink import MemorySink
from navigator.config import rover_config_from_table
from navigator.terrain import TerrainMap
from navigator.terrain_classes import FIRM
from tests.hil.world_harness import DT_NS, scenario_with


def downhill(grade: float, size: tuple[int, int] = (40, 240), res: float = 0.25) -> TerrainMap:
    xs = (np.arange(size[1]) + 0.5) * res
    elevation = np.broadcast_to(-grade * xs[np.newaxis, :], size).copy()
    return TerrainMap(elevation, np.full(size, FIRM, np.uint8), np.zeros(size, bool), res)


def test_braking_downhill_charges_the_pack_by_what_the_controllers_report():
    terrain = downhill(math.tan(math.radians(20.0)))
    scenario = dataclasses.replace(
        scenario_with(""), terrain=terrain, believed_terrain=terrain, obstacles=(), start_xy=(3.0, 5.0),
        start_yaw_rad=0.0,
    )  # fmt: skip
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    clock, sink = SimClock(), MemorySink()
    currents, integral_wh, reported = [], 0.0, []
    with lockstep_wires(config.can, clock=clock) as wires:
        codec = VescCodec.for_profile(config.vesc)
        link = CanLink(wires.onboard_bus, codec, clock, sink)
        with SimWorld(
            scenario, config.vehicle, codec, clock, wires.sim_bus, wires.sim_mavlink, sink, 1
        ) as world:
            for tick in range(400):
                clock.advance(DT_NS)
                step = world.tick(DT_NS / 1e9)
                integral_wh += world.battery.voltage_v * world.battery.current_a * DT_NS / 1e9 / 3600.0
                currents.append((step.motor_currents_a, world.battery.current_a))
                if tick % 2 == 0:
                    link.poll()
                    link.send_wheel_speeds([0.5] * 6)
                    reported.append(sum(r.input_current_a for r in link.readings()))
        link.close()
    assert world.body.speed > 0.5  # the rover runs ahead of its wheels: they brake
    for motor_currents, battery_current in currents[-100:]:
        assert all(current < 0.0 for current in motor_currents)
        assert battery_current < 0.0  # the six return more than the electronics take
    assert max(battery for _, battery in currents) > ELECTRONICS_CURRENT_A  # it drew while it pulled away
    # The controllers' reports (STATUS_4 input current, 0.1 A steps, 10 Hz) say what the pack took.
    assert reported[-1] == pytest.approx(currents[-1][1] - ELECTRONICS_CURRENT_A, abs=0.35)
    assert reported[-1] < 0.0
    assert world.battery.charge_used_ah < max_used_ah(currents)
    assert world.battery.energy_wh == pytest.approx(integral_wh, rel=1e-12)


def max_used_ah(currents: list[tuple[object, float]]) -> float:
    """The most charge the pack had given at any tick (the rectangle rule, as Battery.draw counts it)."""
    used, most = 0.0, 0.0
    for _, battery_current in currents:
        used += battery_current * DT_NS / 1e9 / 3600.0
        most = max(most, used)
    return most
