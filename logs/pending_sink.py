"""A sink for records made before their destination exists: held in order, then passed on.

``rover run`` opens its links before its recording, so a link that does not open leaves no file behind;
but a link takes its sink when it is built. It gets this one, which holds whatever is published until
``connect`` names the destination (the recording, with the live stream beside it), passes the held records
on in order with their own log times, and from then on passes every record straight through.

Single-threaded, like ``navigator.deferred_sink``: links that record from another thread queue their
records and publish them from the loop's thread.
"""

from __future__ import annotations

from logs.encoding import EncodedSink, Message
from logs.errors import RecordingError


class PendingSink:
    """Holds records until ``connect``; then a pass-through to the connected sink. Takes pre-encoded
    records too (an ``EncodedSink``), so links in front of it encode each message once."""

    def __init__(self) -> None:
        # topic, log time, message, and its encoded bytes when a link handed them over (else None)
        self._held: list[tuple[str, int, Message, bytes | None]] = []
        self._target: EncodedSink | None = None

    @property
    def held(self) -> int:
        """How many records wait for ``connect``."""
        return len(self._held)

    def publish(self, topic: str, log_time_ns: int, message: Message) -> None:
        if self._target is None:
            self._held.append((topic, log_time_ns, message, None))
        else:
            self._target.publish(topic, log_time_ns, message)

    def publish_encoded(self, topic: str, log_time_ns: int, message: Message, data: bytes) -> None:
        if self._target is None:
            self._held.append((topic, log_time_ns, message, data))
        else:
            self._target.publish_encoded(topic, log_time_ns, message, data)

    def connect(self, target: EncodedSink) -> None:
        """Pass the held records to ``target``, in order, and everything after them; once only."""
        if self._target is not None:
            raise RecordingError("this PendingSink is already connected to its destination")
        self._target = target
        held, self._held = self._held, []
        for topic, log_time_ns, message, data in held:
            if data is None:
                target.publish(topic, log_time_ns, message)
            else:
                target.publish_encoded(topic, log_time_ns, message, data)
