"""Busy-polling in the sensor-paced loop, on a simulated clock whose ``wait`` wakes late (as an OS does):
a polled sample starts its tick at once, the polling is bounded around the expected sample, a silent
sensor costs one bounded spin and then falls back to the deadline, and 0 turns it off."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

from logs.clock import SimClock
from navigator.paced_loop import DEADLINE_GRACE, SampleInterval, SensorPacedScheduler
from tests.runtime.fake_sensor import FakeSensor

MS = 1_000_000
PERIOD = 20 * MS
WAKE_LATE = 600_000  # the OS wakes a waiting loop 0.6 ms after the datagram lands
POLL_COST = 5_000  # one non-blocking poll


@dataclass
class LateWakingLink(FakeSensor):
    polling_ns: int = 0  # simulated time spent in poll()
    polls_by_time: list[int] = field(default_factory=list)

    def wait(self, seconds: float) -> None:
        now = self.clock.now_ns()
        wake = now + max(1, round(seconds * 1e9))
        pending = self.arrivals[self.read :]
        if pending and now < pending[0] + WAKE_LATE < wake:
            wake = pending[0] + WAKE_LATE
        self.clock.advance(max(1, wake - now))

    def poll(self) -> bool:
        self.clock.advance(POLL_COST)
        self.polling_ns += POLL_COST
        self.polls_by_time.append(self.clock.now_ns())
        return self.read < len(self.arrivals) and self.arrivals[self.read] <= self.clock.now_ns()


def _run(
    arrivals: list[int], busy_poll_ns: int, duration_ns: int
) -> tuple[LateWakingLink, list[tuple[int, int]]]:
    clock = SimClock()
    link = LateWakingLink(clock, arrivals)
    ticks: list[tuple[int, int]] = []

    def tick(trigger_ns: int | None) -> None:
        ticks.append((clock.now_ns(), -1 if trigger_ns is None else trigger_ns))
        clock.advance(300_000)

    SensorPacedScheduler(
        clock,
        1e9 / PERIOD,
        tick,
        ingest=link.ingest,
        wait=link.wait,
        poll=link.poll,
        busy_poll_ns=busy_poll_ns,
    ).run(duration_ns)
    return link, ticks


def test_a_polled_sample_starts_its_tick_at_once_instead_of_when_the_os_wakes_the_loop() -> None:
    arrivals = [round(3.3 * MS) + k * PERIOD for k in range(50)]
    polled, polled_ticks = _run(arrivals, MS, arrivals[-1] + MS)
    _, waited_ticks = _run(arrivals, 0, arrivals[-1] + MS)
    # Without polling every tick starts when the wait wakes, 0.6 ms after the sample landed.
    assert all(
        start - arrival == WAKE_LATE for (start, _), arrival in zip(waited_ticks, arrivals, strict=True)
    )
    # With it, from the second sample on (the first one sets the grid) the tick starts within two polls.
    late = [start - arrival for (start, _), arrival in zip(polled_ticks, arrivals, strict=True)]
    assert late[0] == WAKE_LATE and max(late[1:]) <= 2 * POLL_COST
    # Polling costs about the window before each of the 49 samples: 1 ms of the 20 ms period, not more.
    assert 45 * MS <= polled.polling_ns <= 49 * (MS + 2 * POLL_COST)


def test_a_silent_sensor_costs_one_bounded_spin_then_the_loop_ticks_on_its_deadlines() -> None:
    arrivals = [round(3.3 * MS) + k * PERIOD for k in range(10)]
    last = arrivals[-1]
    link, ticks = _run(arrivals, MS, last + 500 * MS)
    after = [t for t in link.polls_by_time if t > last + POLL_COST]
    # One window around where the next sample was due (expected +- 1 ms), then no more polling at all.
    assert after and min(after) >= last + PERIOD - MS and max(after) <= last + PERIOD + MS + POLL_COST
    deadline_ticks = [start for start, trigger in ticks if trigger == -1]
    assert deadline_ticks[0] <= last + PERIOD + round(DEADLINE_GRACE * PERIOD) + MS
    assert {b - a for a, b in itertools.pairwise(deadline_ticks)} == {PERIOD}


def test_the_interval_is_the_median_gap_and_the_grid_follows_the_earliest_arrivals() -> None:
    interval = SampleInterval(PERIOD)
    for k in range(9):
        interval.observe(k * PERIOD + (3 * MS if k == 4 else 0))  # one sample 3 ms late
    assert interval.interval_ns == PERIOD  # a running mean would be 0.3 ms off after it
    assert interval.grid_ns == 8 * PERIOD
    interval.observe(9 * PERIOD + 2 * MS)  # late: the grid moves a tenth of the way
    assert interval.grid_ns == 9 * PERIOD + 200_000
    interval.observe(10 * PERIOD - 100_000)  # earlier than the grid: it moves there at once
    assert interval.grid_ns == 10 * PERIOD - 100_000
    assert interval.expected_ns(10 * PERIOD + 5 * MS) == 11 * PERIOD - 100_000
