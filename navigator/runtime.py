"""The real-time scheduler: a fixed-rate control loop, measurements fused as they arrive in between.

Ticks are due at ``start + k * period`` (absolute deadlines, so no drift). Between ticks the loop waits
in short slices and calls ``ingest`` so the estimator is current when the tick comes. With ``spin_ns`` the
last stretch before a deadline is spun on the clock instead (``navigator.precise_wait``), so a tick starts
on time rather than when the OS gets round to waking the loop; that needs a clock that moves by itself.
A tick that runs late by more than a whole period skips the missed ticks (counted in ``overruns``)
instead of bursting.
The stop flag is polled every slice, so SIGINT/SIGTERM handlers only set it; the caller then stops the
wheels and closes the recording.

Each tick records its start-to-start period and the stack's sensor-to-command latency into bounded
arrays (``TimingStats``), summarised as percentiles at the end.
"""

from __future__ import annotations

import gc
import logging
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from logs.clock import NS_PER_S, Clock
from navigator.precise_wait import spin_until

_log = logging.getLogger(__name__)

# Keep at most this many samples (an hour at 50 Hz); older ones are overwritten, so memory is bounded.
MAX_SAMPLES = 180_000
# Wait for input in slices of at most this long, so a measurement is fused soon after it arrives.
WAIT_SLICE_NS = 1_000_000
# While the real-time loop runs, a thread that wants the GIL gets it after at most this long (Python's
# default is 5 ms): the control thread, woken by a sensor sample, must not wait 5 ms for the planner
# worker or another thread (the in-process simulator of ``rover bench runtime``) to let go.
REALTIME_SWITCH_INTERVAL_S = 0.0002


@contextmanager
def realtime_switch_interval(interval_s: float = REALTIME_SWITCH_INTERVAL_S) -> Iterator[None]:
    """Shorten the interpreter's thread switch interval for the ``with`` block (it is process-wide)."""
    previous = sys.getswitchinterval()
    sys.setswitchinterval(interval_s)
    try:
        yield
    finally:
        sys.setswitchinterval(previous)


def freeze_start_up_heap() -> None:
    """Collect once, then move every object alive now (modules, the map, compiled kernels, the links) to
    the collector's permanent generation (``gc.freeze``), just before a real-time loop starts.

    Measured in ``rover bench runtime`` (20 s, 140 000 objects alive after start-up): a full (generation
    2) collection stopped every thread for 35-50 ms, twice in 20 s, whichever thread triggered it; the
    control thread missed two periods each time. Frozen objects are never scanned again, so the full
    collections that remain look only at what the run allocates. Garbage from start-up is collected
    first, so nothing unreachable is kept forever.
    """
    gc.collect()
    gc.freeze()


def percentiles_ms(values_ns: np.ndarray | Sequence[int]) -> dict[str, float | None]:
    """p50, p99 and max of nanosecond samples, in milliseconds; None when there are none (JSON null: a NaN
    made the recording's ``runtime`` metadata JSON that strict readers such as jq refuse)."""
    values = np.asarray(values_ns, dtype=np.float64)
    if values.size == 0:
        return {"p50_ms": None, "p99_ms": None, "max_ms": None}
    p50, p99 = np.percentile(values, [50, 99])
    return {"p50_ms": float(p50) / 1e6, "p99_ms": float(p99) / 1e6, "max_ms": float(values.max()) / 1e6}


class RingStats:
    """The last ``capacity`` int samples, in a preallocated array (no growth in a long run)."""

    def __init__(self, capacity: int = MAX_SAMPLES) -> None:
        self._data = np.zeros(capacity, dtype=np.int64)
        self._count = 0

    def add(self, value: int) -> None:
        self._data[self._count % len(self._data)] = value
        self._count += 1

    @property
    def count(self) -> int:
        return self._count

    def values(self) -> np.ndarray:
        return self._data[: min(self._count, len(self._data))]

    def summary_ms(self) -> dict[str, float | None]:
        """p50, p99 and max in milliseconds (``percentiles_ms``)."""
        return percentiles_ms(self.values())


@dataclass
class TimingStats:
    jitter_ns: RingStats  # |actual period - nominal period|
    latency_ns: RingStats  # sensor arrival -> wheel command
    tick_ns: RingStats  # time spent in one tick
    overruns: int = 0
    ticks: int = 0
    sensor_ticks: int = 0  # started by the pacing measurement (navigator.paced_loop)
    deadline_ticks: int = 0  # started by the fixed-rate fallback deadline (the pacing sensor was late)
    last_start_ns: int | None = None  # the last tick's start, for the next one's period

    @classmethod
    def empty(cls) -> TimingStats:
        return cls(RingStats(), RingStats(), RingStats())

    def add_tick(self, start_ns: int, end_ns: int, nominal_period_ns: int) -> int | None:
        """Count a tick that ran from ``start_ns`` to ``end_ns``: its time, and the jitter of its
        start-to-start period, which it returns (None for the first tick)."""
        self.ticks += 1
        self.tick_ns.add(end_ns - start_ns)
        period = None if self.last_start_ns is None else start_ns - self.last_start_ns
        if period is not None:
            self.jitter_ns.add(abs(period - nominal_period_ns))
        self.last_start_ns = start_ns
        return period

    def summary(self) -> dict[str, object]:
        return {
            "ticks": self.ticks,
            "overruns": self.overruns,
            "sensor_ticks": self.sensor_ticks,
            "deadline_ticks": self.deadline_ticks,
            "jitter": self.jitter_ns.summary_ms(),
            "latency": self.latency_ns.summary_ms(),
            "tick_time": self.tick_ns.summary_ms(),
        }

    def describe(self) -> str:
        """One line for a person: ticks and what started them, overruns, jitter / latency / tick time."""

        def triple(ring: RingStats) -> str:
            if ring.count == 0:
                return "none"
            figures = ring.summary_ms()
            return f"{figures['p50_ms']:.2f} / {figures['p99_ms']:.2f} / {figures['max_ms']:.2f} ms"

        return (
            f"{self.ticks} ticks ({self.sensor_ticks} sensor, {self.deadline_ticks} deadline), "
            f"{self.overruns} overruns; p50 / p99 / max: jitter {triple(self.jitter_ns)}, "
            f"latency {triple(self.latency_ns)}, tick time {triple(self.tick_ns)}"
        )


class FixedRateScheduler:
    """Calls ``tick`` at ``rate_hz`` on ``clock``; ``ingest`` while waiting; ``wait(seconds)`` to idle.

    ``latency`` (optional) returns the stack's last sensor-to-command latency after each tick.
    ``spin_ns`` (default 0: none): spin this last stretch before each deadline instead of waiting (no
    ``ingest`` in it); only with a real clock. ``due_ns`` is the running tick's deadline.
    """

    def __init__(
        self,
        clock: Clock,
        rate_hz: float,
        tick: Callable[[], None],
        *,
        ingest: Callable[[], object] | None = None,
        wait: Callable[[float], None],
        latency: Callable[[], int | None] | None = None,
        stop: threading.Event | None = None,
        spin_ns: int = 0,
    ) -> None:
        if not rate_hz > 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        if spin_ns < 0:
            raise ValueError(f"spin_ns must be >= 0, got {spin_ns}")
        self._clock = clock
        self.period_ns = round(NS_PER_S / rate_hz)
        self._spin_ns = spin_ns
        self._tick = tick
        self._ingest = ingest
        self._wait = wait
        self._latency = latency
        self.stop = stop or threading.Event()
        self.stats = TimingStats.empty()
        # The deadline of the tick being run (``start + k * period``), whenever it actually started: a tick
        # that stands for a hardware timer's tick (the simulated peer's sensors) reads its time here.
        self.due_ns = 0

    def run(self, duration_ns: int | None = None) -> TimingStats:
        """Run until ``stop`` is set (or ``duration_ns`` has passed); returns the timing statistics."""
        start = self._clock.now_ns()
        end = None if duration_ns is None else start + duration_ns
        due = start
        while not self.stop.is_set():
            now = self._clock.now_ns()
            if end is not None and now >= end:
                break
            if due - now > self._spin_ns:
                if self._ingest is not None:
                    self._ingest()
                remaining = due - self._clock.now_ns() - self._spin_ns
                if remaining > 0:
                    self._wait(min(remaining, WAIT_SLICE_NS) / NS_PER_S)
                continue
            if now < due:
                now = spin_until(self._clock, due)
            tick_start = now
            self.due_ns = due
            self._tick()
            tick_end = self._clock.now_ns()
            self.stats.add_tick(tick_start, tick_end, self.period_ns)
            self.stats.deadline_ticks += 1
            if self._latency is not None:
                latency = self._latency()
                if latency is not None:
                    self.stats.latency_ns.add(latency)
            due += self.period_ns
            if tick_end - due > self.period_ns:
                missed = (tick_end - due) // self.period_ns
                self.stats.overruns += int(missed)
                due += missed * self.period_ns
                _log.warning("control loop overran: skipped %d tick(s)", missed)
        return self.stats
