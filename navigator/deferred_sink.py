"""A sink that can hold records back while the control loop is on its sensor-to-command path.

Recording a message (JSON, MCAP write, Zenoh put) costs tens of microseconds; between a pacing sample's
arrival and the wheel command there are about ten of them (the sample's raw frame and decoded topic, the
estimator's innovation, the command frames themselves). Held, each costs a list append; they are passed
on, in order and with their own log times, right after the command is on the bus. Nothing is dropped
or reordered, so the recording is the same message sequence as without holding.

Single-threaded by design: the control loop's thread publishes and releases (links that record from
another thread queue their records and publish them from the loop's thread, as ``CanLink`` does).
"""

from __future__ import annotations

from logs.encoding import EncodedSink
from logs.sink import Message, MessageSink


def deferred_sink(inner: MessageSink) -> DeferredSink:
    """A ``DeferredSink`` in front of ``inner``; one that also takes pre-encoded records when ``inner``
    does (links such as ``CanLink`` check for ``EncodedSink`` and then skip a second encoding)."""
    return EncodedDeferredSink(inner) if isinstance(inner, EncodedSink) else DeferredSink(inner)


class DeferredSink:
    """Passes every record to ``inner``; between ``hold()`` and ``release()`` it queues them instead."""

    def __init__(self, inner: MessageSink) -> None:
        self._inner = inner
        # topic, log time, message, and its encoded bytes when a link handed them over (else None)
        self._held: list[tuple[str, int, Message, bytes | None]] = []
        self._holding = False

    @property
    def holding(self) -> bool:
        return self._holding

    def publish(self, topic: str, log_time_ns: int, message: Message) -> None:
        if self._holding:
            self._held.append((topic, log_time_ns, message, None))
        else:
            self._inner.publish(topic, log_time_ns, message)

    def hold(self) -> None:
        """Queue records from now on (again holding is harmless)."""
        self._holding = True

    def release(self) -> None:
        """Publish everything queued, in order, and stop holding."""
        self._holding = False
        held, self._held = self._held, []
        for topic, log_time_ns, message, data in held:
            self._forward(topic, log_time_ns, message, data)

    def _forward(self, topic: str, log_time_ns: int, message: Message, data: bytes | None) -> None:
        # Plain inner sink: nothing was handed over encoded (``data`` is None here).
        self._inner.publish(topic, log_time_ns, message)


class EncodedDeferredSink(DeferredSink):
    """A ``DeferredSink`` over an ``EncodedSink``: pre-encoded records are held and passed on as such."""

    def __init__(self, inner: MessageSink) -> None:
        if not isinstance(inner, EncodedSink):
            raise TypeError(f"{type(inner).__name__} does not take pre-encoded records")
        super().__init__(inner)
        self._encoded_inner: EncodedSink = inner

    def publish_encoded(self, topic: str, log_time_ns: int, message: Message, data: bytes) -> None:
        if self._holding:
            self._held.append((topic, log_time_ns, message, data))
        else:
            self._encoded_inner.publish_encoded(topic, log_time_ns, message, data)

    def _forward(self, topic: str, log_time_ns: int, message: Message, data: bytes | None) -> None:
        if data is None:
            self._encoded_inner.publish(topic, log_time_ns, message)
        else:
            self._encoded_inner.publish_encoded(topic, log_time_ns, message, data)
