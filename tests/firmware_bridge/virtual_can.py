"""Helpers for tests: a pair of python-can virtual buses on a channel no other test uses."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from contextlib import contextmanager

import can

from firmware_bridge.vesc import VescCodec, VescProfile
from firmware_bridge.vesc_dbc import load_vesc_database

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
