"""The sensor-synchronous control loop: a tick as soon as the pacing measurement is in, a deadline if not.

Flight stacks run their main loop off the IMU sample (ArduPilot waits for the next IMU sample, then runs
the fast loop on it), so the command always answers the newest measurement and the sensor-to-command
latency is the tick's own compute time, not the wait for the next fixed-rate tick. Here:

* between ticks the loop calls ``ingest`` (read the links, fuse what arrived); ``ingest`` returns the
  receive time (onboard clock) of the newest *pacing* measurement it fused, or ``None``;
* a pacing measurement starts a tick at once, handing its receive time to ``tick`` (the stack measures
  the latency from it), unless the previous tick started less than the minimum gap ago: a pacing sensor
  faster than the control rate is decimated that way (its sample is fused, just not acted on alone);
* if no pacing measurement comes, a tick starts at the fallback deadline, ``period + grace`` after the
  previous tick, and then every ``period`` on an absolute grid (no drift) until the sensor is back, so a
  silent sensor never stops the loop and every failsafe keeps being judged;
* a tick that ends past the next deadline is followed by one tick at once; the deadlines missed beyond
  that one are skipped and counted (``overruns``), and the grid starts again from the late tick.

The minimum gap is ``period - interval / 2`` (at least ``period / 2``), where ``interval`` is the pacing
sensor's measured sample interval: a sensor at the control rate ticks on every sample even when samples
arrive a little early, and a 2x, 4x, 8x faster one ticks on every 2nd, 4th, 8th sample.

Jitter stays what it was: ``|start-to-start period - nominal period|`` over consecutive ticks.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass

from logs.clock import NS_PER_S, Clock
from navigator.runtime import WAIT_SLICE_NS, TimingStats

_log = logging.getLogger(__name__)

# After the last tick, wait this fraction of a period beyond the nominal period for the pacing sensor
# before ticking on the deadline: a sample a few ms late still paces the loop.
DEADLINE_GRACE = 0.5
# The measured sample interval follows new intervals with this weight (about the last 10 samples).
_INTERVAL_WEIGHT = 0.1


@dataclass(frozen=True)
class TickSample:
    """One tick as the loop measured it (clock ns)."""

    start_ns: int
    period_ns: int | None  # since the previous tick's start; None for the first tick
    tick_ns: int  # time spent in the tick
    latency_ns: int | None  # the stack's sensor-to-command latency; None if no pacing sample fed the tick
    trigger: str  # "sensor" or "deadline"
    overruns: int  # deadlines skipped after this tick


class SampleInterval:
    """The pacing sensor's sample interval, a running average of the gaps between its samples.

    Gaps longer than two control periods are outages, not the sensor's rate, and are left out.
    """

    def __init__(self, period_ns: int) -> None:
        self._period_ns = period_ns
        self.interval_ns = float(period_ns)
        self._last_ns: int | None = None

    def observe(self, received_ns: int) -> None:
        if self._last_ns is not None:
            gap = received_ns - self._last_ns
            if 0 < gap <= 2 * self._period_ns:
                self.interval_ns += _INTERVAL_WEIGHT * (gap - self.interval_ns)
        self._last_ns = received_ns

    def min_gap_ns(self) -> int:
        return int(max(self._period_ns - self.interval_ns / 2, self._period_ns / 2))


class SensorPacedScheduler:
    """Runs ``tick(trigger_ns)`` on each pacing measurement (``ingest`` returns its receive time), with a
    fixed-rate fallback at ``rate_hz``; ``wait(seconds)`` idles until input may have arrived.

    ``latency`` (optional) returns the stack's sensor-to-command latency of the tick just run;
    ``on_tick`` (optional) gets every ``TickSample`` (the ``runtime/timing`` publisher uses it).
    """

    def __init__(
        self,
        clock: Clock,
        rate_hz: float,
        tick: Callable[[int | None], None],
        *,
        ingest: Callable[[], int | None],
        wait: Callable[[float], None],
        latency: Callable[[], int | None] | None = None,
        on_tick: Callable[[TickSample], None] | None = None,
        stop: threading.Event | None = None,
    ) -> None:
        if not rate_hz > 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        self._clock = clock
        self.period_ns = round(NS_PER_S / rate_hz)
        self._grace_ns = round(self.period_ns * DEADLINE_GRACE)
        self._tick = tick
        self._ingest = ingest
        self._wait = wait
        self._latency = latency
        self._on_tick = on_tick
        self.stop = stop or threading.Event()
        self.stats = TimingStats.empty()
        self.interval = SampleInterval(self.period_ns)
        self._previous_start: int | None = None
        self._deadline = 0

    def run(self, duration_ns: int | None = None) -> TimingStats:
        """Run until ``stop`` is set (or ``duration_ns`` has passed); returns the timing statistics."""
        start = self._clock.now_ns()
        end = None if duration_ns is None else start + duration_ns
        # The first tick waits up to one period for the sensor, then goes on the deadline.
        self._deadline = start + self.period_ns
        while not self.stop.is_set():
            now = self._clock.now_ns()
            if end is not None and now >= end:
                break
            received = self._ingest()
            if received is not None:
                self.interval.observe(received)
                now = self._clock.now_ns()
                if self._previous_start is None or now - self._previous_start >= self.interval.min_gap_ns():
                    self._run_tick(now, received)
                    continue
            now = self._clock.now_ns()
            if now >= self._deadline:
                self._run_tick(now, None)
                continue
            self._wait(min(self._deadline - now, WAIT_SLICE_NS) / NS_PER_S)
        return self.stats

    def _run_tick(self, start: int, trigger_ns: int | None) -> None:
        self._tick(trigger_ns)
        end = self._clock.now_ns()
        stats = self.stats
        stats.ticks += 1
        stats.tick_ns.add(end - start)
        period = None if self._previous_start is None else start - self._previous_start
        if period is not None:
            stats.jitter_ns.add(abs(period - self.period_ns))
        self._previous_start = start
        latency = self._latency() if self._latency is not None else None
        if trigger_ns is not None:
            stats.sensor_ticks += 1
            # From the sensor's tick the next deadline is a period plus grace away; deadline ticks keep
            # to their absolute grid so a silent sensor leaves a steady fixed-rate loop.
            self._deadline = start + self.period_ns + self._grace_ns
        else:
            stats.deadline_ticks += 1
            self._deadline += self.period_ns
        if latency is not None:
            stats.latency_ns.add(latency)
        missed = 0
        if end >= self._deadline:
            # Late past the next deadline: one tick at once (it is due), the deadlines beyond it skipped
            # (counted), and the grid starts again from that tick, so there is no burst of catch-up ticks.
            missed = (end - self._deadline) // self.period_ns
            if missed:
                stats.overruns += int(missed)
                _log.warning("control loop overran: skipped %d tick(s)", missed)
            self._deadline = end
        if self._on_tick is not None:
            trigger = "deadline" if trigger_ns is None else "sensor"
            self._on_tick(TickSample(start, period, end - start, latency, trigger, int(missed)))
