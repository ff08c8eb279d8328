"""The shipped example configs say what works: each MAVLink connection the hardware example shows opens.

The example once said serial MAVLink was unsupported while the link had a serial transport; its
commented alternatives are now checked against the link itself, over a pseudo-terminal.
"""

from __future__ import annotations

import os
import re
import time
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_link import MavlinkLink
from firmware_bridge.mavlink_stream import SerialTransport
from firmware_bridge.mavlink_transport import open_transport
from logs.clock import SimClock
from logs.sink import MemorySink
from navigator.config import load_rover_config

EXAMPLE = Path(__file__).resolve().parents[2] / "configs" / "rover.example-hardware.toml"
SHOWN = re.compile(r'^#\s*connection\s*=\s*"([^"]+)"', re.MULTILINE)
CONNECTION_LINE = re.compile(r'^connection\s*=\s*"[^"]+"', re.MULTILINE)
DEVICE = re.compile(r"/dev/[^:,]+")


def serial_connections_shown() -> list[str]:
    return [c for c in SHOWN.findall(EXAMPLE.read_text()) if DEVICE.search(c)]


def test_the_hardware_example_shows_a_serial_connection() -> None:
    assert serial_connections_shown(), f"{EXAMPLE.name} shows no serial MAVLink connection"


@pytest.mark.parametrize("shown", serial_connections_shown())
def test_each_serial_connection_shown_loads_and_hears_the_autopilot(tmp_path: Path, shown: str) -> None:
    controller, device = os.openpty()
    try:
        # The example's own spelling and baud, on a pseudo-terminal instead of the real device.
        connection = DEVICE.sub(os.ttyname(device), shown)
        config_path = tmp_path / "rover.toml"
        config_path.write_text(CONNECTION_LINE.sub(f'connection = "{connection}"', EXAMPLE.read_text()))
        config = load_rover_config(config_path)
        transport = open_transport(config.mavlink.connection)
        assert isinstance(transport, SerialTransport)
        with MavlinkLink(transport, SimClock(7), MemorySink()) as link:
            autopilot = mavlink2.MAVLink(None, 1, 1)
            heartbeat = mavlink2.MAVLink_heartbeat_message(
                mavlink2.MAV_TYPE_GROUND_ROVER, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4, 3
            )
            os.write(controller, bytes(heartbeat.pack(autopilot)))
            deadline = time.monotonic() + 5.0
            while link.last_heartbeat_ns is None and time.monotonic() < deadline:
                link.poll()
                time.sleep(0.001)
            assert link.last_heartbeat_ns == 7
    finally:
        os.close(controller)
        os.close(device)
