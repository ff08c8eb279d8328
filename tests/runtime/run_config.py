"""The smallest config `rover run` accepts on a virtual CAN bus, for the tests that start it for real."""

from __future__ import annotations


def rover_run_config(
    rover_id: str, channel: str, connection: str = "udpin:127.0.0.1:0", *, zenoh: bool = False
) -> str:
    """TOML text: CAN on python-can ``virtual`` ``channel``, MAVLink on ``connection``, a 10 m map."""
    return f"""
rover_id = "{rover_id}"
[can]
interface = "virtual"
channel = "{channel}"
[mavlink]
connection = "{connection}"
[zenoh]
enabled = {"true" if zenoh else "false"}
[map]
kind = "procedural"
size_m = [10.0, 10.0]
resolution_m = 0.5
"""
