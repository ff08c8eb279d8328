"""The onboard stack on ``navigator.runtime.FixedRateScheduler``: ticks on the clock, not on the sensor.

The comparison peer of ``rover bench runtime`` for the sensor-synchronous loop ``rover run`` uses. Between
ticks the scheduler calls ``ingest``, which reads the links and fuses what arrived (so a sample's receive
time is when it landed, within a wait slice); the next tick answers the newest pacing sample among them,
and its sensor-to-command latency is measured from that sample's receive time: up to a period of waiting
plus the tick. A tick with no pacing sample since the last one reads the links itself, as in lockstep.
"""

from __future__ import annotations

from typing import Protocol


class PacedStack(Protocol):
    """What this needs of ``navigator.onboard.OnboardStack``."""

    def ingest(self) -> int | None: ...

    def step(self, trigger_ns: int | None = None) -> None: ...


class FixedRateFeed:
    """``ingest`` and ``tick`` for ``FixedRateScheduler`` around a stack."""

    def __init__(self, stack: PacedStack) -> None:
        self._stack = stack
        self._pending_ns: int | None = None

    def ingest(self) -> None:
        received = self._stack.ingest()
        if received is not None:
            self._pending_ns = received

    def tick(self) -> None:
        trigger, self._pending_ns = self._pending_ns, None
        self._stack.step(trigger)
