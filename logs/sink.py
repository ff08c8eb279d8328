"""Where components put what they observe and decide: one call, ``publish(topic, log_time_ns, message)``.

The MCAP recorder and the Zenoh telemetry stream are both sinks; a ``FanoutSink`` feeds several. Messages
are plain JSON-able dicts laid out as the topic's schema in ``logs.topics`` says.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, Protocol

Message = dict[str, Any]


class MessageSink(Protocol):
    def publish(self, topic: str, log_time_ns: int, message: Message) -> None: ...


class NullSink:
    """Discards everything; for components run without recording."""

    def publish(self, topic: str, log_time_ns: int, message: Message) -> None:
        return None


@dataclass
class MemorySink:
    """Keeps every message in order; the test double for a recorder."""

    records: list[tuple[str, int, Message]] = field(default_factory=list)

    def publish(self, topic: str, log_time_ns: int, message: Message) -> None:
        self.records.append((topic, log_time_ns, message))

    def on(self, topic: str) -> list[Message]:
        return [m for t, _, m in self.records if t == topic]


class FanoutSink:
    """Publishes every message to each of several sinks, in the order given."""

    def __init__(self, sinks: Iterable[MessageSink]) -> None:
        self._sinks = tuple(sinks)

    def publish(self, topic: str, log_time_ns: int, message: Message) -> None:
        for sink in self._sinks:
            sink.publish(topic, log_time_ns, message)
