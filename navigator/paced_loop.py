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

The minimum gap is ``period - interval / 2`` (at least ``period / 2``) since the last *sensor* tick (a
deadline tick does not count: a sample landing just after one starts its own tick, or a sensor back in a
new phase would be dropped for good), where ``interval`` is the pacing sensor's measured sample
interval: a sensor at the control rate ticks on every sample even when samples arrive a little early, and
a 2x, 4x, 8x faster one ticks on every 2nd, 4th, 8th sample.

Busy-polling (``busy_poll_ns`` > 0 and a ``poll`` to call): waking from ``select`` when the sample lands
takes the OS 0.1-1 ms on a VM (an idle vCPU halts), and that lands on the tick's start. So from
``busy_poll_ns`` before the next tick-starting sample is expected (the last one plus the measured
interval, on a grid that follows the earliest arrivals) the loop polls without blocking until it is in,
for at most ``busy_poll_ns`` past the expected time (in slices of at most a wait slice, with an
``ingest`` between them), then goes back to waiting: a late or silent sensor costs one bounded spin (for
the first sample it misses, none after). Its CPU cost is about ``busy_poll_ns`` per sample on time.

Jitter stays what it was: ``|start-to-start period - nominal period|`` over consecutive ticks.
"""

from __future__ import annotations

import logging
import math
import statistics
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from logs.clock import NS_PER_S, Clock
from navigator.runtime import WAIT_SLICE_NS, TimingStats

_log = logging.getLogger(__name__)

# After the last tick, wait this fraction of a period beyond the nominal period for the pacing sensor
# before ticking on the deadline: a sample a few ms late still paces the loop.
DEADLINE_GRACE = 0.5
# The measured sample interval is the median of this many last gaps: one late sample (a gap too long,
# then one too short) moves a running average by a tenth of its lateness, and the median not at all.
_INTERVAL_GAPS = 9
# A sample later than the grid moves the grid this fraction of the way (an earlier one all the way).
_GRID_FOLLOW = 0.1


@dataclass(frozen=True)
class TickSample:
    """One tick as the loop measured it (clock ns)."""

    start_ns: int
    period_ns: int | None  # since the previous tick's start; None for the first tick
    tick_ns: int  # time spent in the tick
    latency_ns: int | None  # the stack's sensor-to-command latency; None if no pacing sample fed the tick
    trigger: str  # "sensor" or "deadline"
    overruns: int  # deadlines skipped after this tick
    trigger_ns: int | None = None  # receive time of the pacing sample that started the tick
    # Every pacing sample this tick's command answered, when that is more than ``latency_ns``'s one (the
    # phase-locked loop: a late sample is answered by the next tick with the next sample); empty: just it.
    more_latencies_ns: tuple[int, ...] = ()

    def latencies_ns(self) -> tuple[int, ...]:
        """Sensor-to-command latency of each pacing sample this tick answered."""
        if self.more_latencies_ns:
            return self.more_latencies_ns
        return () if self.latency_ns is None else (self.latency_ns,)


class SampleInterval:
    """The pacing sensor's sample interval, the median of the last gaps between its samples, and the
    grid its samples land on.

    Gaps longer than two control periods are outages, not the sensor's rate, and are left out. The grid
    follows the *earliest* arrivals: a sample is only ever late (the sender, the transport, our wake-up
    delay it), so one earlier than the grid moves the grid to it at once, one later only a little. A
    prediction from the last receive time alone would carry each late wake-up into the next prediction.
    """

    def __init__(self, period_ns: int) -> None:
        self._period_ns = period_ns
        self.interval_ns = float(period_ns)
        self._gaps: deque[int] = deque(maxlen=_INTERVAL_GAPS)
        self.last_ns: int | None = None
        self.grid_ns: float | None = None  # where the last sample should have landed

    def observe(self, received_ns: int) -> None:
        if self.last_ns is not None:
            self._note_gap(received_ns - self.last_ns)
        self.last_ns = received_ns
        self._follow(received_ns)

    def _note_gap(self, gap_ns: int) -> None:
        """The interval from the gap just seen (a subclass may read the rate differently)."""
        if 0 < gap_ns <= 2 * self._period_ns:
            self._gaps.append(gap_ns)
            self.interval_ns = float(statistics.median(self._gaps))

    def _follow(self, received_ns: int) -> None:
        """Move the grid: to an earlier sample at once, toward a later one a little."""
        grid = self.grid_ns
        if grid is None or not 0 < received_ns - grid <= 2 * self._period_ns:
            self.grid_ns = float(received_ns)
            return
        predicted = grid + max(1, round((received_ns - grid) / self.interval_ns)) * self.interval_ns
        late = received_ns - predicted
        self.grid_ns = float(received_ns) if late <= 0 else predicted + _GRID_FOLLOW * late

    def expected_ns(self, not_before_ns: int) -> int | None:
        """When the first sample at or after ``not_before_ns`` should land, on the grid; None before the
        first sample."""
        if self.grid_ns is None:
            return None
        steps = max(1, math.ceil((not_before_ns - self.grid_ns) / self.interval_ns))
        return round(self.grid_ns + steps * self.interval_ns)

    def min_gap_ns(self) -> int:
        return int(max(self._period_ns - self.interval_ns / 2, self._period_ns / 2))


class SensorPacedScheduler:
    """Runs ``tick(trigger_ns)`` on each pacing measurement (``ingest`` returns its receive time), with a
    fixed-rate fallback at ``rate_hz``; ``wait(seconds)`` idles until input may have arrived.

    ``latency`` (optional) returns the stack's sensor-to-command latency of the tick just run;
    ``on_tick`` (optional) gets every ``TickSample`` (the ``runtime/timing`` publisher uses it);
    ``poll`` (optional) says without blocking whether input is waiting, for busy-polling ``busy_poll_ns``
    around the expected sample (0: never; see the module doc).
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
        poll: Callable[[], bool] | None = None,
        busy_poll_ns: int = 0,
    ) -> None:
        if not rate_hz > 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        if busy_poll_ns < 0:
            raise ValueError(f"busy_poll_ns must be >= 0, got {busy_poll_ns}")
        self._clock = clock
        self.period_ns = round(NS_PER_S / rate_hz)
        self._grace_ns = round(self.period_ns * DEADLINE_GRACE)
        self._tick = tick
        self._ingest = ingest
        self._wait = wait
        self._latency = latency
        self._on_tick = on_tick
        self._poll = poll if busy_poll_ns > 0 else None
        self._busy_poll_ns = busy_poll_ns
        self.busy_polls = 0  # spins started
        self.stop = stop or threading.Event()
        self.stats = TimingStats.empty()
        self.interval = SampleInterval(self.period_ns)
        # Decimation counts from the last *sensor* tick: measured from a deadline tick, a sample landing
        # just after each one would be dropped for good and the loop would stay on its deadlines.
        self._previous_sensor_start: int | None = None
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
                if (
                    self._previous_sensor_start is None
                    or now - self._previous_sensor_start >= self.interval.min_gap_ns()
                ):
                    self._run_tick(now, received)
                    continue
            now = self._clock.now_ns()
            if now >= self._deadline:
                self._run_tick(now, None)
                continue
            wake = min(self._deadline, now + WAIT_SLICE_NS)
            spin = self._spin_window(now)
            if spin is not None:
                spin_from, spin_to = spin
                if spin_from <= now:
                    self._busy_poll(min(spin_to, wake))
                    continue
                wake = min(wake, spin_from)
            self._wait((wake - now) / NS_PER_S)
        return self.stats

    def _spin_window(self, now: int) -> tuple[int, int] | None:
        """Where to busy-poll for the next tick-starting sample: (from, to), or None (no poll, no sample
        yet, that sample already missed, or the window over)."""
        if self._poll is None:
            return None
        last = self.interval.last_ns
        if last is None:
            return None
        previous = self._previous_sensor_start
        not_before = last if previous is None else previous + self.interval.min_gap_ns()
        expected = self.interval.expected_ns(not_before)
        # Only the first tick-starting sample after the last one: once that is missed the sensor is late
        # or silent, and the loop waits (its deadline is the fallback) without spinning again.
        if expected is None or expected - last > 1.5 * self.period_ns or now >= expected + self._busy_poll_ns:
            return None
        return expected - self._busy_poll_ns, expected + self._busy_poll_ns

    def _busy_poll(self, until_ns: int) -> None:
        assert self._poll is not None
        self.busy_polls += 1
        poll, clock = self._poll, self._clock
        while not poll() and clock.now_ns() < until_ns:
            pass

    def _run_tick(self, start: int, trigger_ns: int | None) -> None:
        self._tick(trigger_ns)
        end = self._clock.now_ns()
        stats = self.stats
        period = stats.add_tick(start, end, self.period_ns)
        latency = self._latency() if self._latency is not None else None
        if trigger_ns is not None:
            self._previous_sensor_start = start
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
            self._on_tick(TickSample(start, period, end - start, latency, trigger, int(missed), trigger_ns))
