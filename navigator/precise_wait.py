"""Waiting for a deadline on the monotonic clock without the OS's wake-up overshoot: sleep, then spin.

A sleep to a deadline wakes late by the scheduler's wake-up latency. On the firecracker build VM (an idle
vCPU halts and the host has to wake it) ``time.sleep`` to a 10 ms deadline overshot p50 0.16 / p99 0.4-0.8
/ max 4 ms. A real IMU samples on a hardware timer, so the simulated autopilot must not inherit that; and a
fixed-rate control loop that starts its ticks late has that much jitter. So: sleep until ``spin_ns``
before the deadline, then spin on the clock for the rest. The spin absorbs any overshoot up to ``spin_ns``;
it costs about ``spin_ns`` of CPU per wait (measured on that VM, 100 waits a second: 0.5 ms spin 4 % of a
core, 1 ms 9 %, 2 ms 19 %). Host stalls (the VM not running at all) are beyond any of this.

The spin holds the GIL between the interpreter's forced switches; it is for a process's (or thread's)
only waiting point, not for a loop that has to read its inputs meanwhile.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from logs.clock import NS_PER_S, Clock

# 1 ms: absorbs the p99 of the sleep overshoot measured above at about 9 % of a core at 100 waits a second.
DEFAULT_SPIN_NS = 1_000_000


def spin_until(clock: Clock, deadline_ns: int) -> int:
    """Spin on ``clock`` until ``deadline_ns``; returns the first reading at or after it (never before)."""
    now = clock.now_ns()
    while now < deadline_ns:
        now = clock.now_ns()
    return now


def sleep_until(
    clock: Clock,
    deadline_ns: int,
    spin_ns: int = DEFAULT_SPIN_NS,
    sleep: Callable[[float], None] = time.sleep,
) -> int:
    """Sleep until ``spin_ns`` before ``deadline_ns``, then spin; returns the clock's reading at or after
    the deadline (never before). ``spin_ns`` 0 is a plain sleep (with its overshoot) that still never
    returns early. ``clock`` must be one that moves by itself (a simulated clock would spin forever)."""
    if spin_ns < 0:
        raise ValueError(f"spin_ns must be >= 0, got {spin_ns}")
    now = clock.now_ns()
    # Sleep in a loop: a sleep can end early (a signal handler that did not raise).
    while deadline_ns - now > spin_ns:
        sleep((deadline_ns - now - spin_ns) / NS_PER_S)
        now = clock.now_ns()
    return spin_until(clock, deadline_ns)
