"""``runtime/timing``: the control loop's timing over the last window (about a second), on the record.

The scheduler hands over every tick (``navigator.paced_loop.TickSample``); once a window of
``window_ns`` has passed, one message goes to the sink with, over that window: period jitter
(``|start-to-start period - nominal|``), sensor-to-command latency and tick time as p50 / p99 / max,
how many ticks ran and what started them (pacing sample or deadline), overruns, and running totals. The
window's samples live in lists that are cleared on every publish, so memory does not grow.
"""

from __future__ import annotations

from typing import Any

from logs import topics
from logs.clock import NS_PER_S, Clock
from logs.sink import MessageSink
from navigator.paced_loop import TickSample
from navigator.runtime import percentiles_ms

WINDOW_NS = NS_PER_S


def _window_percentiles(values: list[int]) -> dict[str, Any]:
    """p50 / p99 / max in milliseconds (None when there are no samples) and the sample count."""
    return {**percentiles_ms(values), "samples": len(values)}


class TimingPublisher:
    """Collects ``TickSample``s and publishes one ``runtime/timing`` message per window."""

    def __init__(
        self, clock: Clock, sink: MessageSink, nominal_period_ns: int, window_ns: int = WINDOW_NS
    ) -> None:
        self._clock = clock
        self._sink = sink
        self._nominal_ns = nominal_period_ns
        self._window_ns = window_ns
        self._window_start = clock.now_ns()
        self._jitter: list[int] = []
        self._latency: list[int] = []
        self._tick: list[int] = []
        self._counts = {"sensor": 0, "deadline": 0}
        self._overruns = 0
        self.ticks_total = 0
        self.overruns_total = 0
        self.published = 0

    def observe(self, sample: TickSample) -> None:
        if sample.period_ns is not None:
            self._jitter.append(abs(sample.period_ns - self._nominal_ns))
        # Every sample the tick answered, as the loop's own statistics count them.
        self._latency.extend(sample.latencies_ns())
        self._tick.append(sample.tick_ns)
        self._counts[sample.trigger] = self._counts.get(sample.trigger, 0) + 1
        self._overruns += sample.overruns
        self.ticks_total += 1
        self.overruns_total += sample.overruns
        now = self._clock.now_ns()
        if now - self._window_start >= self._window_ns:
            self._publish(now)

    def _publish(self, now: int) -> None:
        self._sink.publish(
            topics.RUNTIME_TIMING,
            now,
            {
                "timestamp": topics.stamp(now),
                "window_s": (now - self._window_start) / NS_PER_S,
                "nominal_period_ms": self._nominal_ns / 1e6,
                "ticks": len(self._tick),
                "sensor_ticks": self._counts.get("sensor", 0),
                "deadline_ticks": self._counts.get("deadline", 0),
                "overruns": self._overruns,
                "jitter": _window_percentiles(self._jitter),
                "latency": _window_percentiles(self._latency),
                "tick_time": _window_percentiles(self._tick),
                "last_tick_ms": self._tick[-1] / 1e6 if self._tick else None,
                "ticks_total": self.ticks_total,
                "overruns_total": self.overruns_total,
            },
        )
        self.published += 1
        self._window_start = now
        self._jitter.clear()
        self._latency.clear()
        self._tick.clear()
        self._counts = {"sensor": 0, "deadline": 0}
        self._overruns = 0
