"""Run a simulated rover process at a real-time priority, as the hardware it stands for keeps its own time.

The real rover's IMU and motor controllers are separate hardware on their own timers: nothing the
companion computer runs can delay their sends. A simulated rover that shares the machine with the stack
under test is an ordinary process, and at an ordinary priority every thread the stack wakes (Zenoh's
runtime, the planning worker, the recorder) can preempt it just as its IMU frame is due. On the 2-core
build VM that made the simulated IMU's sends late by p99 2.0-2.4 ms (``rover bench runtime --trace``),
and the loop under test took the sensor's lateness as its own jitter. ``SCHED_FIFO`` puts the simulated
hardware ahead of every normal-policy thread, which is where hardware is: ahead of the computer's
scheduler altogether. Only the simulated rover gets it; the stack keeps the policy it is deployed with.

The priority needs privilege (root or ``CAP_SYS_NICE``); without it the peer runs as before and the
returned text says so, for the benchmark's table.
"""

from __future__ import annotations

import os

MAX_FIFO_PRIORITY = 99
# What the benchmark and the soak give their simulated rover: any real-time priority puts it ahead of the
# stack's normal-policy threads, and a low one leaves room above it for the kernel's own.
PEER_FIFO_PRIORITY = 10


def raise_to_fifo(pid: int, priority: int) -> str:
    """Put process ``pid`` (its main thread and the threads it starts later) on ``SCHED_FIFO`` at
    ``priority`` (1-99; 0 leaves it as it is); says what was applied."""
    if not 0 <= priority <= MAX_FIFO_PRIORITY:
        raise ValueError(f"a SCHED_FIFO priority is 1-{MAX_FIFO_PRIORITY} (0: leave it), got {priority}")
    if priority == 0:
        return "normal scheduling (--peer-fifo 0)"
    try:
        os.sched_setscheduler(pid, os.SCHED_FIFO, os.sched_param(priority))
    except (PermissionError, OSError) as err:
        return f"normal scheduling (SCHED_FIFO {priority} refused: {err.strerror or err})"
    return f"SCHED_FIFO {priority}, as timer-driven hardware"
