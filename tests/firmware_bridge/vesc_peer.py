"""The simulated VESC bank as a separate process: the far end of a cross-process CAN link test.

Run as ``python -m tests.firmware_bridge.vesc_peer INTERFACE CHANNEL [PORT]``. It writes ``ready`` on
stdout once its bus is open, runs the six controllers in real time, and exits when stdin closes (the
test's way of stopping it: no signals, no sleeps to synchronise on).
"""

from __future__ import annotations

import sys
import threading
from typing import Any

import can

from hil.vesc_sim import SimVescBank
from logs.clock import MonotonicClock
from tests.firmware_bridge.virtual_can import make_codec

STEP_S = 0.005


def run(interface: str, channel: str, port: int | None) -> None:
    stop = threading.Event()

    def wait_for_stdin_to_close() -> None:
        sys.stdin.read()
        stop.set()

    threading.Thread(target=wait_for_stdin_to_close, daemon=True).start()
    kwargs: dict[str, Any] = {} if port is None else {"port": port}
    bus = can.Bus(interface=interface, channel=channel, ignore_config=True, **kwargs)
    try:
        clock = MonotonicClock()
        bank = SimVescBank(bus, make_codec(), clock)
        sys.stdout.write("ready\n")
        sys.stdout.flush()
        last_ns = clock.now_ns()
        while not stop.wait(STEP_S):
            bank.poll()
            now_ns = clock.now_ns()
            bank.step((now_ns - last_ns) / 1e9)
            last_ns = now_ns
    finally:
        bus.shutdown()


if __name__ == "__main__":
    run(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else None)
