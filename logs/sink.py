"""Where components put what they observe and decide: one call, ``publish(topic, log_time_ns, message)``.

The MCAP recorder and the Zenoh telemetry stream are both sinks; a ``FanoutSink`` feeds several. Messages
are plain JSON-able dicts laid out as the topic's schema in ``logs.topics`` says.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import NoReturn, Protocol

import orjson

from logs.encoding import ORJSON_OPTIONS, EncodedSink, Message, bytes_only_sink, encode_message, json_default
from logs.errors import LogsError

__all__ = ["FanoutSink", "MemorySink", "Message", "MessageSink", "NullSink"]


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
    """Publishes every message to each of several sinks, in the order given.

    The recorder and the live stream carry the same bytes, so the message is encoded once and those bytes
    go to every sink that takes them (``EncodedSink``); other sinks get the message itself. A message
    that cannot be encoded goes to every sink as is, so each reports it in its own words. When every sink
    records bytes alone (``BytesSink``), so does the fan-out: ``publish_bytes`` takes bytes without a
    message (``publish_bytes_many`` several of one topic and log time), and ``publish`` hands each sink
    the bytes through it.
    """

    def __init__(self, sinks: Iterable[MessageSink]) -> None:
        # (sink, the same sink when it takes bytes, else None): typed so that the hot loop needs no cast.
        # The method is looked up per call, not bound here, so a benchmark that wraps a sink's methods after
        # wiring (``rover bench hil``) still sees every call.
        self._sinks: tuple[tuple[MessageSink, EncodedSink | None], ...] = tuple(
            (sink, sink if isinstance(sink, EncodedSink) else None) for sink in sinks
        )
        self._any_encoded = any(encoded is not None for _, encoded in self._sinks)
        # BytesSink (logs.encoding): when every sink records bytes alone, so does the fan-out, and the
        # producers that can format their bytes directly (the CAN link's frames) need build no dict.
        bytes_sinks = tuple(bytes_only_sink(sink) for sink, _ in self._sinks)
        self._bytes_sinks = tuple(sink for sink in bytes_sinks if sink is not None)
        self.records_bytes_only = len(self._bytes_sinks) == len(self._sinks)

    def publish(self, topic: str, log_time_ns: int, message: Message) -> None:
        data: bytes | None = None
        if self._any_encoded:
            try:
                # encode_message's first step inline (orjson with its options): a Python frame fewer on
                # every dict message of a trial. What orjson refuses goes through encode_message itself.
                # default and option positional (orjson takes them so): no keyword names to match per call.
                data = orjson.dumps(message, json_default, ORJSON_OPTIONS)
            except TypeError:
                data = self._encode_refused(message)
        if data is None:
            for sink, _ in self._sinks:
                sink.publish(topic, log_time_ns, message)
        elif self.records_bytes_only:
            # The usual wiring (recorder and Zenoh): the bytes straight to each, a layer fewer per message.
            for bytes_sink in self._bytes_sinks:
                bytes_sink.publish_bytes(topic, log_time_ns, data)
        else:
            self.publish_encoded(topic, log_time_ns, message, data)

    @staticmethod
    def _encode_refused(message: Message) -> bytes | None:
        """``encode_message`` for what orjson refused: its fallback's bytes, or None when JSON cannot hold
        the message (each sink is then handed the message, to report it in its own words)."""
        try:
            return encode_message(message)
        except (TypeError, ValueError):
            return None

    def publish_encoded(self, topic: str, log_time_ns: int, message: Message, data: bytes) -> None:
        for sink, encoded in self._sinks:
            if encoded is not None:
                encoded.publish_encoded(topic, log_time_ns, message, data)
            else:
                sink.publish(topic, log_time_ns, message)

    def publish_bytes(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """A message's bytes alone to every sink (only when ``records_bytes_only``)."""
        if not self.records_bytes_only:
            self._refuse_bytes(topic)
        for sink in self._bytes_sinks:
            sink.publish_bytes(topic, log_time_ns, data)

    def publish_bytes_many(self, topic: str, log_time_ns: int, datas: Sequence[bytes]) -> None:
        """Several messages' bytes of one topic and log time to every sink, in one call per sink (only when
        ``records_bytes_only``). Each sink gets them all in order before the next sink gets any: the
        recorder's order is the same as one by one, and each sink's own order too."""
        if not self.records_bytes_only:
            self._refuse_bytes(topic)
        for sink in self._bytes_sinks:
            sink.publish_bytes_many(topic, log_time_ns, datas)

    def _refuse_bytes(self, topic: str) -> NoReturn:
        raise LogsError(
            f"a sink of this fan-out needs each message itself, not only its bytes; "
            f"cannot pass on {topic!r} as bytes"
        )
