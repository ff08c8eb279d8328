"""The world's time starts with the world: moving obstacles do not depend on what the clock read then.

The real-time peer runs on the OS monotonic clock, which counts from the machine's boot (10^6 s after
eleven days up); a lockstep world's clock starts at 0. Both must put a cart where its scenario says.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from firmware_bridge.vesc import VescCodec
from hil.lockstep import lockstep_wires
from hil.world import SimWorld
from logs.clock import SimClock, to_ns
from logs.reader import read_metadata
from logs.recorder import McapRecorder
from logs.settings import parse_toml
from logs.sink import MemorySink
from logs.topics import TRUTH_CONTACTS
from navigator.config import rover_config_from_table
from tests.hil.world_harness import scenario_with

# The rover stands at its start (2, 2). The cart waits 600 s at (2, 7), then walks down x = 2 at 1 m/s:
# over the rover at 605 s from the world's start, at (2, 0.5) at 606.5 s, back up at (2, 5) at 611 s.
CART = """
[[moving_obstacles]]
id = "cart"
radius_m = 0.4
speed_mps = 1.0
start_s = 600.0
waypoints = [[2.0, 7.0], [2.0, 0.5]]
"""
# A machine up for about eleven days. Not a whole number of the cart's 13 s round trip, so a world that
# moved the cart on the raw clock could not put it in the same place by chance.
UPTIME_NS = to_ns(1_000_013.0)
# Seconds from the world's start: waiting, just started, closing in, over the rover, gone by.
TIMES_S = (300.0, 600.5, 603.0, 605.0, 611.0)


@contextmanager
def world_from(start_ns: int, sink: MemorySink) -> Iterator[tuple[SimWorld, SimClock]]:
    scenario = scenario_with(CART, duration_s=700.0)  # long enough for the cart to start moving
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    clock = SimClock(start_ns)
    with lockstep_wires(config.can, clock=clock) as wires:
        codec = VescCodec.for_profile(config.vesc)
        with SimWorld(
            scenario, config.vehicle, codec, clock, wires.sim_bus, wires.sim_mavlink, sink, scenario.seed
        ) as world:
            yield world, clock


def _cart_over_time(start_ns: int) -> tuple[list[tuple[float, float]], list[float]]:
    """Where perception saw the cart at each of TIMES_S, and when (s from the world's start) the truth
    recorded a collision with it."""
    sink = MemorySink()
    seen: list[tuple[float, float]] = []
    with world_from(start_ns, sink) as (world, clock):
        for t_s in TIMES_S:
            clock.advance(start_ns + to_ns(t_s) - clock.now_ns())
            world.tick(0.01)  # the truth's contact check runs at the clock's now
            cart = next(o for o in world.perception.poll() if o.obstacle_id == "cart")
            seen.append((cart.x, cart.y))
    hits = [
        (ns - start_ns) / 1e9
        for topic, ns, contact in sink.records
        if topic == TRUTH_CONTACTS and contact["kind"] == "collision"
    ]
    return seen, hits


def test_a_world_on_a_clock_started_long_ago_moves_the_cart_as_one_started_at_zero() -> None:
    at_zero, hits_at_zero = _cart_over_time(0)
    after_uptime, hits_after_uptime = _cart_over_time(UPTIME_NS)
    # The scenario's cart: waits at its first waypoint until 600 s, then 1 m/s down x = 2.
    expected = [(2.0, 7.0), (2.0, 6.5), (2.0, 4.0), (2.0, 2.0), (2.0, 5.0)]
    assert np.array(at_zero) == pytest.approx(np.array(expected))
    assert np.array(after_uptime) == pytest.approx(np.array(expected))
    # The truth recorded the cart running over the rover at the same world time in both.
    assert hits_at_zero == pytest.approx([605.0])
    assert hits_after_uptime == pytest.approx([605.0])


def test_the_world_records_its_start_for_the_metrics() -> None:
    buffer = io.BytesIO()
    with McapRecorder(buffer) as recorder, world_from(UPTIME_NS, MemorySink()) as (world, _clock):
        world.record_start(recorder)
    assert read_metadata(io.BytesIO(buffer.getvalue()))["world"] == {"epoch_ns": str(UPTIME_NS)}
