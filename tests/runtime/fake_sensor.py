"""A pacing sensor on a simulated clock, and a loop's tick and wait around it, for the real-time loops'
tests (``navigator.paced_loop``, ``navigator.phase_locked_loop``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Self

from logs.clock import SimClock
from navigator.paced_loop import TickSample

TICK_COST = 300_000  # each tick takes 0.3 ms of (simulated) time until its command


@dataclass
class FakeSensor:
    """Samples land at ``arrivals`` (clock ns); ``ingest`` returns the newest one not yet read."""

    clock: SimClock
    arrivals: list[int]
    read: int = 0

    def ingest(self) -> int | None:
        newest = None
        while self.read < len(self.arrivals) and self.arrivals[self.read] <= self.clock.now_ns():
            newest = self.arrivals[self.read]
            self.read += 1
        return newest


@dataclass
class SensorLoop:
    """A scheduler's callbacks on a simulated clock: ``tick`` notes (start, trigger) and costs
    ``TICK_COST``; ``wait`` sleeps like select on the sensor's socket; ``latency`` is the stack's."""

    clock: SimClock
    sensor: FakeSensor
    ticks: list[tuple[int, int | None]] = field(default_factory=list)
    samples: list[TickSample] = field(default_factory=list)

    @classmethod
    def on(cls, arrivals: list[int]) -> Self:
        clock = SimClock()
        return cls(clock, FakeSensor(clock, arrivals))

    def tick(self, trigger_ns: int | None) -> None:
        self.ticks.append((self.clock.now_ns(), trigger_ns))
        self.clock.advance(TICK_COST)

    def wait(self, seconds: float) -> None:
        # Like select on the socket: wake at the timeout or when the next sample lands, whichever first.
        wake = self.clock.now_ns() + max(1, round(seconds * 1e9))
        pending = self.sensor.arrivals[self.sensor.read :]
        if pending and self.clock.now_ns() < pending[0] < wake:
            wake = pending[0]
        self.clock.advance(max(1, wake - self.clock.now_ns()))

    def latency(self) -> int | None:
        """From the trigger the last tick was given to now (its command)."""
        return None if self.ticks[-1][1] is None else self.clock.now_ns() - self.ticks[-1][1]
