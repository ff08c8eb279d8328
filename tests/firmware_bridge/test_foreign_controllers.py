"""Status frames from controllers the config does not name are pointed out once per id, with the fix."""

from __future__ import annotations

import dataclasses
import logging

import can
import pytest

from firmware_bridge.can_link import CanLink
from firmware_bridge.vesc_dbc import frame_id
from logs.clock import SimClock
from logs.sink import MemorySink
from tests.firmware_bridge.virtual_can import TEST_PROFILE, make_codec, virtual_bus_pair

STATUS, STATUS_5, SET_RPM = 9, 27, 3


def test_status_from_an_unconfigured_id_is_named_once_with_the_fix(caplog: pytest.LogCaptureFixture) -> None:
    # The controllers answer as 1..6 (their own setting); the config says 11..16.
    profile = dataclasses.replace(TEST_PROFILE, controller_ids=(11, 12, 13, 14, 15, 16))
    with virtual_bus_pair("foreign") as (ours, theirs):
        link = CanLink(ours, make_codec(profile), SimClock(), MemorySink())
        for _ in range(3):
            for command in (STATUS, STATUS_5):
                for controller in (1, 2):
                    theirs.send(can.Message(arbitration_id=frame_id(command, controller), data=bytes(8)))
        # Not a status (another companion commanding id 3): says nothing about the controllers' ids.
        theirs.send(can.Message(arbitration_id=frame_id(SET_RPM, 3), data=bytes(4)))
        with caplog.at_level(logging.WARNING, logger="firmware_bridge.can_link"):
            for _ in range(20):
                link.poll()
        link.close()
    named = [r.getMessage() for r in caplog.records if "does not name" in r.getMessage()]
    assert len(named) == 2, named
    assert named[0].startswith("CAN: VESC status frames from controller id 1, which [vesc] controller_ids ")
    assert "[11, 12, 13, 14, 15, 16]" in named[0] and "put its id there" in named[0]
    assert "controller id 2" in named[1]
    assert link.counters.unknown_id == 13
