"""Wiring for lockstep HIL in one process: both ends of the CAN bus and of the MAVLink link.

The onboard side gets exactly what it gets on the rover (a python-can ``Bus`` and a MAVLink transport); the
simulator holds the other ends. CAN uses python-can's ``virtual`` interface on a channel name private to
this trial, MAVLink an in-memory byte pipe, so frames cross as real bytes and nothing touches a network.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Literal

import can

from firmware_bridge.can_link import CanConfig, CanLink, open_bus
from firmware_bridge.mavlink_link import MavlinkLink
from firmware_bridge.mavlink_transport import PipeEnd, memory_pipe_pair
from firmware_bridge.vesc import VescCodec
from hil.lockstep_bus import lockstep_bus_pair
from logs.clock import Clock
from logs.sink import MessageSink
from navigator.config import RoverConfig

_channel_numbers = itertools.count()

CanBackend = Literal["lockstep", "virtual"]
CAN_BACKENDS: tuple[CanBackend, ...] = ("lockstep", "virtual")


@dataclass
class LockstepWires:
    onboard_bus: can.BusABC
    sim_bus: can.BusABC
    onboard_mavlink: PipeEnd
    sim_mavlink: PipeEnd


@contextmanager
def lockstep_wires(
    can_config: CanConfig, *, clock: Clock | None = None, can_backend: CanBackend = "lockstep"
) -> Iterator[LockstepWires]:
    """Open a private CAN channel and a MAVLink byte pipe; shut both CAN ends on exit."""
    channel = f"{can_config.channel}-lockstep-{next(_channel_numbers)}"
    onboard_bus: can.BusABC
    sim_bus: can.BusABC
    if can_backend == "lockstep":
        onboard_bus, sim_bus = lockstep_bus_pair(channel, clock)
    elif can_backend == "virtual":
        onboard_config = dataclasses.replace(can_config, interface="virtual", channel=channel)
        onboard_bus = open_bus(onboard_config)
        sim_bus = open_bus(onboard_config)
    else:
        raise ValueError(f"lockstep CAN backend must be one of {CAN_BACKENDS}, got {can_backend!r}")
    onboard_pipe, sim_pipe = memory_pipe_pair()
    try:
        yield LockstepWires(onboard_bus, sim_bus, onboard_pipe, sim_pipe)
    finally:
        onboard_bus.shutdown()
        sim_bus.shutdown()


def onboard_links(
    config: RoverConfig, can_bus: can.BusABC, mavlink: PipeEnd, clock: Clock, sink: MessageSink
) -> tuple[CanLink, MavlinkLink]:
    """The onboard stack's CAN and MAVLink links on the rover's ends of the wires, as ``rover run`` makes
    them from the config (``can_bus``: ``LockstepWires.onboard_bus``, or what a fault made of it)."""
    can_link = CanLink(can_bus, VescCodec.for_profile(config.vesc), clock, sink, config=config.can)
    mavlink_link = MavlinkLink(
        mavlink,
        clock,
        sink,
        system_id=config.mavlink.system_id,
        component_id=config.mavlink.component_id,
    )
    return can_link, mavlink_link
