"""``runtime/timing``: one message per window with the window's own percentiles, laid out as registered."""

from __future__ import annotations

from typing import Any

import pytest

from logs import topics
from logs.clock import SimClock
from logs.sink import MemorySink
from navigator.paced_loop import TickSample
from navigator.timing_topic import TimingPublisher

MS = 1_000_000
PERIOD = 20 * MS


def _matches(message: Any, schema: dict[str, Any]) -> bool:
    """The message has exactly the schema's required keys, recursively for nested objects."""
    if schema.get("type") != "object":
        return True
    if set(message) != set(schema["required"]):
        return False
    return all(_matches(message[key], sub) for key, sub in schema["properties"].items())


def test_one_message_per_window_with_that_windows_figures() -> None:
    clock = SimClock()
    sink = MemorySink()
    publisher = TimingPublisher(clock, sink, PERIOD)
    # Window 1: 50 sensor ticks, period 20 ms +- 0.5 ms, latency 1 ms; the last one overran by 2 ticks.
    for k in range(50):
        clock.advance(PERIOD + (500_000 if k % 2 else -500_000))
        publisher.observe(
            TickSample(clock.now_ns(), PERIOD + 500_000, 800_000, MS, "sensor", 2 if k == 49 else 0)
        )
    # Window 2: deadline ticks only (no latency samples).
    for _ in range(50):
        clock.advance(PERIOD)
        publisher.observe(TickSample(clock.now_ns(), PERIOD, 300_000, None, "deadline", 0))
    messages = sink.on(topics.RUNTIME_TIMING)
    assert len(messages) == 2 == publisher.published
    first, second = messages
    assert first["ticks"] == 50 and first["sensor_ticks"] == 50 and first["deadline_ticks"] == 0
    assert first["overruns"] == 2 and first["overruns_total"] == 2
    assert first["jitter"]["p99_ms"] == pytest.approx(0.5)
    assert first["latency"] == {"p50_ms": 1.0, "p99_ms": 1.0, "max_ms": 1.0, "samples": 50}
    assert first["tick_time"]["max_ms"] == pytest.approx(0.8) and first["last_tick_ms"] == pytest.approx(0.8)
    assert second["deadline_ticks"] == 50 and second["overruns"] == 0 and second["ticks_total"] == 100
    assert second["latency"]["samples"] == 0 and second["latency"]["p99_ms"] is None
    assert second["jitter"]["max_ms"] == 0.0
    schema = topics.spec(topics.RUNTIME_TIMING).schema
    assert all(_matches(m, schema) for m in messages)


def test_timing_stats_describe_themselves_in_one_line_even_without_samples() -> None:
    from navigator.runtime import TimingStats

    stats = TimingStats.empty()
    stats.ticks, stats.sensor_ticks, stats.deadline_ticks = 3, 2, 1
    for value in (1_000_000, 2_000_000):
        stats.jitter_ns.add(value)
    line = stats.describe()
    assert line.startswith("3 ticks (2 sensor, 1 deadline), 0 overruns")
    assert "jitter 1.50 / 1.99 / 2.00 ms" in line and "latency none" in line and "nan" not in line


def test_a_tick_that_answered_two_samples_counts_both() -> None:
    clock = SimClock()
    sink = MemorySink()
    publisher = TimingPublisher(clock, sink, PERIOD)
    for k in range(50):
        clock.advance(PERIOD)
        # Tick 10 answered its own sample (1 ms) and the one that missed the tick before (19 ms).
        more = (19 * MS, MS) if k == 10 else ()
        publisher.observe(
            TickSample(clock.now_ns(), PERIOD, 300_000, 19 * MS if more else MS, "sensor", 0, None, more)
        )
    (message,) = sink.on(topics.RUNTIME_TIMING)
    assert message["latency"]["samples"] == 51 and message["latency"]["max_ms"] == 19.0
