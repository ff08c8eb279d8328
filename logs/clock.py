"""Clocks in integer nanoseconds. Every component is handed one; nothing reads wall time behind it."""

from __future__ import annotations

import time
from typing import Protocol

NS_PER_S = 1_000_000_000


class Clock(Protocol):
    """Source of time for a component, in nanoseconds since an arbitrary epoch."""

    def now_ns(self) -> int: ...


class SimClock:
    """A clock that moves only when the lockstep runner advances it."""

    def __init__(self, start_ns: int = 0) -> None:
        if start_ns < 0:
            raise ValueError(f"start_ns must be >= 0, got {start_ns}")
        self._now_ns = start_ns

    def now_ns(self) -> int:
        return self._now_ns

    def advance(self, dt_ns: int) -> int:
        """Move time forward by ``dt_ns`` (> 0) and return the new time."""
        if dt_ns <= 0:
            raise ValueError(f"a simulated clock only moves forward; got dt_ns={dt_ns}")
        self._now_ns += dt_ns
        return self._now_ns


class MonotonicClock:
    """Real time on the rover and in real-time HIL: the OS monotonic clock."""

    def now_ns(self) -> int:
        return time.monotonic_ns()


def seconds(t_ns: int) -> float:
    return t_ns / NS_PER_S


def to_ns(t_s: float) -> int:
    return round(t_s * NS_PER_S)
