"""Helpers for tests: a pair of python-can virtual buses on a channel no other test uses, or of lockstep
buses (``hil.lockstep_bus``, which also move frames in batches: ``BatchBus``), to run one test on both."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Literal

import can

from firmware_bridge.vesc import VescCodec, VescProfile
from firmware_bridge.vesc_dbc import load_vesc_database
from hil.lockstep_bus import lockstep_bus_pair

_channel_numbers = itertools.count()

TEST_PROFILE = VescProfile(
    controller_ids=(1, 2, 3, 4, 5, 6), pole_pairs=7, gear_ratio=20.0, wheel_radius_m=0.15
)


def make_codec(profile: VescProfile = TEST_PROFILE) -> VescCodec:
    return VescCodec(load_vesc_database(profile.controller_ids), profile)


@contextmanager
def virtual_bus_pair(label: str) -> Iterator[tuple[can.BusABC, can.BusABC]]:
    """Two ends of one private virtual channel, shut down afterwards whatever happens."""
    channel = f"test-{label}-{next(_channel_numbers)}"
    a = can.Bus(interface="virtual", channel=channel, ignore_config=True)
    b = can.Bus(interface="virtual", channel=channel, ignore_config=True)
    try:
        yield a, b
    finally:
        a.shutdown()
        b.shutdown()


BusKind = Literal["virtual", "lockstep"]
BUS_KINDS: tuple[BusKind, ...] = ("virtual", "lockstep")


@contextmanager
def bus_pair(kind: BusKind, label: str) -> Iterator[tuple[can.BusABC, can.BusABC]]:
    """Two connected ends of a ``kind`` bus (``BUS_KINDS``), shut down afterwards whatever happens."""
    if kind == "virtual":
        with virtual_bus_pair(label) as pair:
            yield pair
        return
    a, b = lockstep_bus_pair(f"test-{label}-{next(_channel_numbers)}")
    try:
        yield a, b
    finally:
        a.shutdown()
        b.shutdown()
