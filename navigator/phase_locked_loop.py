"""The fixed-rate control loop, phase-locked to the pacing sensor: steady ticks that land just after it.

The two plain loops each give up one of the runtime's two goals (``docs/runtime.md``):

* the sensor-paced loop (``navigator.paced_loop``) starts a tick when the sample lands, so its latency
  is the tick's compute, but its period is the sample's arrival period: every late send of the sensor, and
  every late wake-up of ours, is period jitter;
* a free-running fixed-rate loop (``navigator.runtime.FixedRateScheduler``) ticks on its own clock with a
  precise wait (jitter of microseconds), but at an arbitrary phase to the sensor: a sample waits up to a
  whole period for the tick that answers it.

This loop ticks on its own grid, with the precise wait, and steers that grid so each tick is due
``offset_ns`` after the pacing sample is expected (``SensorGrid``: the grid of its earliest arrivals).
Samples are fused as they land (``ingest`` between ticks, and, when ``poll`` says input waits, during the
spin before a tick as well), so a sample on time is in the estimator when its tick starts, ``offset_ns``
later. Period jitter is the precise wait's plus the steering, which moves the grid by at most ``slew_ns``
a tick; locking on is the exception: when the sensor's phase is first known (or known again after an
outage or an overrun, or when it moved: three samples missed, or samples earlier than the grid by more
than the late wait) the grid moves there in one step.

A sample later than its due time is waited for, but only ``late_wait_ns``: the tick then starts as it
lands (late by at most that much: bounded jitter, and the grid stays where it was). A sample later still
is not waited for: the tick runs on what the estimator has, and the sample is answered by the next tick.
Its latency is counted honestly: every pacing sample fused between two ticks is measured to the command
of the tick after it (the stack measures the newest; an older one adds the gap between the two), so a
sensor that keeps missing its tick shows in the latency figures. Without a pacing sensor (silent, or
never heard), or with one too slow to set every tick's phase (samples more than 1.5 periods apart: a
5-10 Hz GPS on a 50 Hz loop) or at another rate than the loop's or a whole multiple of it, the loop is
a plain fixed-rate loop.

``offset_ns`` and ``late_wait_ns`` are the trade: a sample's usual lateness plus its fusing (~0.3 ms)
should fit in the offset, its rare lateness in the two together; the offset adds to every sample's
latency, the late wait to the jitter of the ticks that use it.
"""

from __future__ import annotations

import logging
import math
import statistics
import threading
from collections import deque
from collections.abc import Callable

from logs.clock import NS_PER_S, Clock
from navigator.paced_loop import SampleInterval, TickSample
from navigator.precise_wait import DEFAULT_SPIN_NS, spin_until
from navigator.runtime import WAIT_SLICE_NS, TimingStats

_log = logging.getLogger(__name__)

# The tick is due this long after the expected sample, and a locked tick whose sample is not in by then
# waits at most the late wait more for it (starting as it lands: jitter bounded by the late wait). Chosen
# by `rover bench runtime` on the 2-core build VM (docs/runtime.md): the sample lands about 0.1-0.3 ms
# after the grid of its earliest arrivals and takes ~0.2 ms to fuse, so with 0.3 + 0.8 ms most ticks start
# as the sample is in (latency: the tick alone), the grid bounds the rest, and under 1 % miss. A 0.8 ms
# offset (with 0.7 ms) added its whole length to every latency: p99 2.3-3.1 ms against 1.4-1.6 ms.
DEFAULT_OFFSET_NS = 300_000
DEFAULT_LATE_WAIT_NS = 800_000
# This many locked ticks in a row whose sample did not come even in the late wait: the sensor's phase has
# moved (or it went silent), and the loop locks on afresh from its next sample instead of steering there.
_RELOCK_AFTER_MISSES = 3
# Steering moves a tick by at most this much (which is then all the jitter it adds).
DEFAULT_SLEW_NS = 50_000
# A sensor not heard for this many periods has lost its phase: the grid runs free until it is back.
_LOST_AFTER_PERIODS = 3
# Samples further apart than this many periods (median gap) cannot set every tick's phase: no lock.
_TOO_SLOW_PERIODS = 1.5
# A median gap further than this fraction of the period from the period or a whole fraction of it is a
# sensor at another rate (40 Hz on a 50 Hz loop): its samples drift through the ticks' phase, no lock.
_OFF_RATE_TOLERANCE = 1 / 8


class SensorGrid(SampleInterval):
    """Where the pacing sensor's samples should land: ``SampleInterval``'s grid through the earliest
    arrivals, spaced at the sensor's interval taken to be the control period or a whole fraction of it (a
    50 or 100 Hz IMU for a 50 Hz loop; the median gap says which).

    Not the measured median gap itself (``SampleInterval`` uses that): for a lock, the interval must be
    unbiased over many periods, and the median of gaps is not when lateness is skewed (samples are only
    ever late), which moved the ticks ahead of the samples by tenths of a millisecond. The sender's clock
    rate differs from ours by parts per million, which the grid's following absorbs.
    """

    def __init__(self, period_ns: int) -> None:
        super().__init__(period_ns)
        # Every gap, long ones too: a 10 Hz GPS on a 50 Hz loop has only gaps of 5 periods, which
        # ``_gaps`` leaves out as outages, so its rate is judged from these.
        self._spacing: deque[int] = deque(maxlen=self._gaps.maxlen)
        self.too_slow = False  # samples further apart than 1.5 periods: they cannot set every tick's phase
        self.off_rate = False  # neither the period nor a whole fraction of it apart: no phase to lock to

    @property
    def rate_known(self) -> bool:
        """At least one gap seen: until then a lock could not tell a 50 Hz sensor from a 10 Hz one."""
        return bool(self._spacing)

    def _note_gap(self, gap_ns: int) -> None:
        if gap_ns > 0:
            self._spacing.append(gap_ns)
            self.too_slow = statistics.median(self._spacing) > _TOO_SLOW_PERIODS * self._period_ns
        if 0 < gap_ns <= 2 * self._period_ns:
            self._gaps.append(gap_ns)
            median = statistics.median(self._gaps)
            per_period = max(1, round(self._period_ns / median))
            self.interval_ns = self._period_ns / per_period
            off_by = abs(median * per_period - self._period_ns)
            self.off_rate = off_by > _OFF_RATE_TOLERANCE * self._period_ns

    def restart(self) -> None:
        """Forget where the samples land (the next one says), keeping the interval."""
        self.grid_ns = None

    def expected_ns(self, not_before_ns: int) -> int | None:
        """When the first sample at or after ``not_before_ns`` should land (the last one's own time
        included); None before the first."""
        if self.grid_ns is None:
            return None
        steps = math.ceil((not_before_ns - self.grid_ns) / self.interval_ns)
        return round(self.grid_ns + steps * self.interval_ns)


class PhaseLockedScheduler:
    """Runs ``tick(trigger_ns)`` every period on ``clock``, the ticks phase-locked ``offset_ns`` after the
    pacing measurement (``ingest`` returns its receive time, or None); ``wait(seconds)`` idles until input
    may have arrived, ``poll()`` says without blocking whether input waits.

    ``latency`` (optional) returns the stack's sensor-to-command latency of the tick just run, measured
    from the ``trigger_ns`` it was given; ``on_tick`` (optional) gets every ``TickSample``.
    ``spin_ns``: the last stretch before each tick is spun on the clock (0: none; a spin needs a clock that
    moves by itself); ``poll`` is only used in spins, so with 0 it is ignored.
    ``late_wait_ns`` defaults to ``DEFAULT_LATE_WAIT_NS``, or half a period when that is shorter (above
    about 700 Hz).
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
        offset_ns: int = DEFAULT_OFFSET_NS,
        late_wait_ns: int | None = None,
        slew_ns: int = DEFAULT_SLEW_NS,
        spin_ns: int = DEFAULT_SPIN_NS,
    ) -> None:
        if not rate_hz > 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        self.period_ns = round(NS_PER_S / rate_hz)
        if late_wait_ns is None:
            # The default must fit every rate the config allows (up to 1000 Hz): at most half a period.
            late_wait_ns = min(DEFAULT_LATE_WAIT_NS, self.period_ns // 2)
        if not 0 <= offset_ns < self.period_ns:
            raise ValueError(f"offset_ns must be in [0, {self.period_ns}), got {offset_ns}")
        if not 0 <= late_wait_ns <= self.period_ns // 2:
            raise ValueError(f"late_wait_ns must be in [0, {self.period_ns // 2}], got {late_wait_ns}")
        if not 0 < slew_ns <= self.period_ns // 2:
            raise ValueError(f"slew_ns must be in (0, {self.period_ns // 2}], got {slew_ns}")
        if spin_ns < 0:
            raise ValueError(f"spin_ns must be >= 0, got {spin_ns}")
        self._clock = clock
        self._tick = tick
        self._ingest = ingest
        self._wait = wait
        self._latency = latency
        self._on_tick = on_tick
        # The poll is only ever spun on (before a tick, and in the late wait); without a spin (a simulated
        # clock, which does not move by itself) the late wait idles in ``wait`` instead.
        self._poll = poll if spin_ns > 0 else None
        self.offset_ns = offset_ns
        self._late_wait_ns = late_wait_ns
        self._slew_ns = slew_ns
        self._spin_ns = spin_ns
        self.stop = stop or threading.Event()
        self.stats = TimingStats.empty()
        self.grid = SensorGrid(self.period_ns)
        self.locked = False
        self.locks = 0  # times the grid jumped to the sensor's phase (first lock, and after outages)
        self.late_waits_missed = 0  # locked ticks whose sample had not come by the end of the late wait
        self._misses_in_a_row = 0
        self._pending: list[int] = []  # receive times of pacing samples fused since the last tick

    def run(self, duration_ns: int | None = None) -> TimingStats:
        """Run until ``stop`` is set (or ``duration_ns`` has passed); returns the timing statistics."""
        start = self._clock.now_ns()
        end = None if duration_ns is None else start + duration_ns
        due = start + self.period_ns
        while not self.stop.is_set():
            now = self._clock.now_ns()
            if end is not None and now >= end:
                break
            if due - now > self._spin_ns:
                self._take(self._ingest())
                remaining = due - self._clock.now_ns() - self._spin_ns
                if remaining > 0:
                    self._wait(min(remaining, WAIT_SLICE_NS) / NS_PER_S)
                continue
            now = self._spin_to(due)
            if self.locked:
                now = self._wait_for_late_sample(due)
            due = self._run_tick(now, due)
        return self.stats

    def _spin_to(self, due: int) -> int:
        """Spin to ``due``, fusing input that lands meanwhile; the clock's reading at or after ``due``."""
        if self._poll is None:
            self._take(self._ingest())
            return spin_until(self._clock, due)
        poll, clock = self._poll, self._clock
        now = clock.now_ns()
        while now < due:
            if poll():
                self._take(self._ingest())
            now = clock.now_ns()
        return now

    def _wait_for_late_sample(self, due: int) -> int:
        """Past ``due`` without this tick's sample (one that landed in the half interval before the tick's
        expected sample, or after): wait for it for the late wait, no longer. Returns the clock's reading."""
        limit = due + self._late_wait_ns
        window_start = due - self.offset_ns - self.grid.interval_ns / 2
        clock = self._clock
        now = clock.now_ns()
        while not self._has_sample_since(window_start) and now < limit:
            if self._poll is not None:
                if self._poll():
                    self._take(self._ingest())
            else:
                self._take(self._ingest())
                if not self._has_sample_since(window_start):
                    self._wait(min(limit - now, WAIT_SLICE_NS) / NS_PER_S)
            now = clock.now_ns()
        if self._has_sample_since(window_start):
            self._misses_in_a_row = 0
            return now
        self.late_waits_missed += 1
        self._misses_in_a_row += 1
        if self._misses_in_a_row >= _RELOCK_AFTER_MISSES:
            # Three in a row: the sensor's phase moved (or it fell silent); lock on afresh from its next
            # sample rather than steer there at the slew rate.
            self.locked = False
            self._misses_in_a_row = 0
            self.grid.restart()
        return now

    def _has_sample_since(self, window_start: float) -> bool:
        return bool(self._pending) and self._pending[-1] >= window_start

    def _take(self, received: int | None) -> None:
        if received is not None:
            self.grid.observe(received)
            self._pending.append(received)

    def _run_tick(self, start: int, due: int) -> int:
        """Run one tick that started at ``start`` (due at ``due``); returns the next tick's due time."""
        pending, self._pending = self._pending, []
        trigger = pending[-1] if pending else None
        answered: tuple[int, ...] = ()
        self._tick(trigger)
        end = self._clock.now_ns()
        stats = self.stats
        period = stats.add_tick(start, end, self.period_ns)
        latency = self._latency() if self._latency is not None else None
        if trigger is None:
            stats.deadline_ticks += 1
            if latency is not None:
                # A sample the tick read itself (it landed after the late wait gave up) is its trigger.
                stats.latency_ns.add(latency)
        else:
            stats.sensor_ticks += 1
            if latency is not None:
                # Each sample fused since the last tick is answered by this command.
                answered = tuple(latency + trigger - received for received in pending)
                for each in answered:
                    stats.latency_ns.add(each)
        following = due + self.period_ns
        missed = 0
        if end >= following:
            # Late past the next tick: that tick runs at once, the ones beyond it are skipped (counted),
            # not burst through, and the grid locks on to the sensor again from there.
            missed = (end - following) // self.period_ns
            if missed:
                stats.overruns += int(missed)
                _log.warning("control loop overran: skipped %d tick(s)", missed)
            self.locked = False
            following = end
        else:
            following = self._next_due(following, end)
        if self._on_tick is not None:
            worst = max(answered) if answered else latency
            kind = "deadline" if trigger is None else "sensor"
            self._on_tick(TickSample(start, period, end - start, worst, kind, int(missed), trigger, answered))
        return following

    def _next_due(self, nominal: int, now: int) -> int:
        """``nominal`` steered toward ``offset_ns`` after the sample expected before it."""
        grid = self.grid
        last = grid.last_ns
        if (
            last is None
            or now - last > _LOST_AFTER_PERIODS * self.period_ns
            or not grid.rate_known
            or grid.too_slow
            or grid.off_rate
        ):
            self.locked = False
            return nominal
        if self.locked:
            expected = grid.expected_ns(round(nominal - self.offset_ns - grid.interval_ns / 2))
            if expected is None:
                return nominal
            error = expected + self.offset_ns - nominal  # within half a sample interval
            if error >= -self._late_wait_ns:
                return nominal + max(-self._slew_ns, min(self._slew_ns, error))
            # The samples now land earlier than the grid by more than the late wait: the sensor's phase
            # moved earlier (a sample is never early by chance: the grid follows the earliest ones). None
            # is missed, so the relock on misses never comes; steering there at the slew took a tick per
            # 0.05 ms, every sample meanwhile waiting that much longer for its command. Lock on afresh.
            self.locked = False
        # Locking on: one step to the tick of the first sample whose tick is still ahead and that the
        # tick just run has not answered (every sample observed so far was pending for it): a sample
        # that landed less than the offset before that tick would otherwise get a second, empty tick
        # an instant later, which waits the late wait and counts a miss.
        expected = grid.expected_ns(max(now - self.offset_ns + 1, round(last + grid.interval_ns / 2)))
        if expected is None:
            return nominal
        self.locked = True
        self.locks += 1
        self._misses_in_a_row = 0
        return expected + self.offset_ns
