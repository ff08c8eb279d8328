"""A fixed pure-Python workload that tells how fast the host runs Python right now.

``rover bench hil`` times it in every round beside the trials. On a shared VM the same code runs up to
twice as long from one minute to the next; when the probe's times spread as the trials' do, the host's
speed moved, not the code's. The work (dict stores and loads, float arithmetic, a method call) is the kind
the trial's loop does, and depends on nothing in this project.
"""

from __future__ import annotations

import time

# About 40 ms on the build VM: long enough to span the host's short stalls, short beside a trial.
PROBE_STEPS = 300_000


class _Accumulator:
    def __init__(self) -> None:
        self.total = 0.0

    def add(self, value: float) -> None:
        self.total += value


def _probe_work(steps: int) -> float:
    table = {key: float(key) for key in range(1024)}
    accumulator = _Accumulator()
    for step in range(steps):
        table[step & 1023] = step * 0.5
        accumulator.add(table[(step * 7) & 1023] * 1e-3)
    return accumulator.total


def time_host_probe(steps: int = PROBE_STEPS) -> float:
    """Wall seconds of one run of the fixed workload."""
    started = time.perf_counter()
    _probe_work(steps)
    return time.perf_counter() - started
