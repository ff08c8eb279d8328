"""``rover run`` opens its MAVLink link with every ``[mavlink]`` setting of the config, not the defaults."""

from __future__ import annotations

import itertools
import socket
import time

from pymavlink.dialects.v20 import common as mavlink2

from logs.clock import SimClock
from logs.settings import parse_toml
from logs.sink import MemorySink
from navigator.config import rover_config_from_table
from navigator.links import open_links

_channels = itertools.count()
KEY = "ab" * 32

CONFIG = """
[can]
interface = "virtual"
channel = "open-links-{n}"
[mavlink]
connection = "udpin:127.0.0.1:0"
link_timeout_s = 0.5
signing_key = "{key}"
rx_budget_bytes_per_s = 20000
"""


def test_signing_link_timeout_and_receive_budget_come_from_the_config() -> None:
    text = CONFIG.format(n=next(_channels), key=KEY)
    config = rover_config_from_table(parse_toml(text, "<test>"))
    clock, sink = SimClock(), MemorySink()
    links = open_links(config, clock, sink)
    station = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        (transport,) = links.pacing_sources  # the MAVLink transport: the IMU paces the loop
        _, port = transport.local_address  # type: ignore[attr-defined]
        # An unsigned disarm from a ground station: with signing on, refused.
        disarm = mavlink2.MAVLink_command_long_message(
            1, 191, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 0, 0, 0, 0, 0, 0
        )
        station.sendto(bytes(disarm.pack(mavlink2.MAVLink(None, 255, 190))), ("127.0.0.1", port))
        # 5 kB of noise: more than the budget's burst (a tenth of a second: 2000 bytes).
        station.sendto(bytes(range(0xFD)) * 20, ("127.0.0.1", port))
        clock.advance(600_000_000)  # past the 0.5 s link timeout, no autopilot heartbeat
        counters = links.mavlink.counters
        readings = []
        deadline = time.monotonic() + 10.0
        while not (counters.signature_rejected and counters.dropped_bytes) and time.monotonic() < deadline:
            readings += links.mavlink.poll()
            time.sleep(0.005)  # loopback datagrams land within microseconds; this only yields the CPU
        assert readings == [] and counters.signature_rejected == 1 and counters.stops_accepted == 0
        assert counters.dropped_bytes > 0
        kinds = [m["kind"] for m in sink.on("safety/events")]
        assert kinds == ["mavlink_link_lost"]
    finally:
        station.close()
        links.mavlink.close()
        links.can.close()
