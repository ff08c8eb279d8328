"""A pacing sensor on a simulated clock, for the sensor-paced loop's tests."""

from __future__ import annotations

from dataclasses import dataclass

from logs.clock import SimClock


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
