"""The bytes of a recorded or streamed message: compact JSON, NaN and infinity as ``null``.

The MCAP recorder and the Zenoh stream carry exactly these bytes, so a ``FanoutSink`` encodes each message
once and hands the same bytes to every sink that takes them (``EncodedSink``).

This sits on the lockstep trial's hot path (~1300 messages per simulated second; a 15x15 covariance in
``estimator/pose`` each tick), so the encoder is orjson: 3-10x faster than the standard library's C
encoder on our messages, numpy arrays and scalars taken directly, NaN and infinity written as ``null`` in
one pass. Its floats are the shortest text that reads back to the same double (``7e-05`` is written
``0.00007``): every reader gets the same numbers as from ``json.dumps``; a test checks the round trip.

What orjson refuses and JSON can still hold (an integer beyond 64 bits, an object with ``tolist``
orjson does not know) goes through the standard library's encoder instead, with the same rules.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any, Protocol, runtime_checkable

import orjson

# The same alias as logs.sink.Message (which imports this module, so it cannot be imported from there).
Message = dict[str, Any]
_SEPARATORS = (",", ":")
# numpy arrays and scalars as JSON numbers and lists: the first try, good for every message whose dict
# keys are all plain str (every message of a trial). orjson refuses any other key (an int, a str subclass,
# an enum) in this form with a TypeError; with OPT_NON_STR_KEYS it takes them all but walks every key of
# every message on its slower general path (~25 % of the encoding of a trial's messages). For plain str
# keys both forms write the same bytes, so a message is tried fast first and only a refused one again.
# Public with ``json_default`` for the one caller that makes encode_message's first step inline, a
# Python frame fewer per message (``logs.sink.FanoutSink.publish``, every dict message of a trial).
ORJSON_OPTIONS = orjson.OPT_SERIALIZE_NUMPY
# ... and int (and other non-str) dict keys as strings, as json.dumps does: the second try.
ORJSON_ANY_KEY_OPTIONS = ORJSON_OPTIONS | orjson.OPT_NON_STR_KEYS
# orjson's words for data nested deeper than it recurses (a cycle, in practice).
_ORJSON_RECURSION = "Recursion limit reached"


def json_default(value: Any) -> Any:
    # numpy scalars and arrays have tolist(); anything else is a caller bug worth a clear error.
    tolist = getattr(value, "tolist", None)
    if tolist is not None:
        return tolist()
    raise TypeError(f"{type(value).__name__} value {value!r} is not JSON-serialisable")


def _finite(value: Any) -> Any:
    """A copy of ``value`` with every NaN / infinity replaced by ``None`` (JSON null)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(item) for item in value]
    tolist = getattr(value, "tolist", None)
    if tolist is not None:
        return _finite(tolist())
    return value


def _encode_with_json(message: Message) -> bytes:
    """The standard library's encoder, for what orjson refuses; same output rules (compact, NaN null)."""
    try:
        repaired = _finite(message)
    except RecursionError as err:
        raise ValueError("message is circular or nested too deeply to encode as JSON") from err
    text = json.dumps(repaired, separators=_SEPARATORS, allow_nan=False, default=json_default)
    return text.encode()


def encode_message(message: Message) -> bytes:
    """Compact JSON bytes of ``message``; NaN and +/-inf become ``null`` (JSON has no NaN).

    Raises ``TypeError`` for values JSON cannot hold and ``ValueError`` for circular data.
    """
    try:
        # default and option positional (orjson takes them so): no keyword names to match per message.
        return orjson.dumps(message, json_default, ORJSON_OPTIONS)
    except TypeError:  # orjson.JSONEncodeError is a TypeError: a key that is not a str, or worse
        pass
    try:
        return orjson.dumps(message, default=json_default, option=ORJSON_ANY_KEY_OPTIONS)
    except TypeError as err:
        if _ORJSON_RECURSION in str(err):
            raise ValueError("message is circular or nested too deeply to encode as JSON") from err
    return _encode_with_json(message)


@runtime_checkable
class EncodedSink(Protocol):
    """A sink that can take a message's bytes from ``encode_message`` instead of encoding it again.

    ``data`` is exactly ``encode_message(message)``; ``message`` rides along for sinks that look inside
    (a rate limiter in front of a publisher does not, but a test double may).
    """

    def publish(self, topic: str, log_time_ns: int, message: Message) -> None: ...

    def publish_encoded(self, topic: str, log_time_ns: int, message: Message, data: bytes) -> None: ...


@runtime_checkable
class BytesSink(Protocol):
    """A sink whose record of a message is its bytes alone: it never looks inside the message.

    The MCAP recorder and the Zenoh publisher are such sinks, and so is a ``FanoutSink`` or a
    ``RateLimitedSink`` with only such sinks behind it (``records_bytes_only`` says whether this one is:
    a sink behind it may need the message itself). A producer whose JSON is cheaper to format than its
    dict (the CAN link's frame records, ~720 per simulated second of a lockstep trial, half the trial's
    messages) asks ``bytes_only_sink`` once and then hands over bytes without building the dict at all.

    ``publish_bytes_many`` takes several messages of one topic at one log time in one call (the CAN link's
    frames of one poll or one command round, 6-18 at a time): the same as ``publish_bytes`` for each in
    turn, with the per-call work (lookups, checks, a rate limiter's decision) done once for them all.
    """

    records_bytes_only: bool

    def publish_bytes(self, topic: str, log_time_ns: int, data: bytes) -> None: ...

    def publish_bytes_many(self, topic: str, log_time_ns: int, datas: Sequence[bytes]) -> None: ...


def bytes_only_sink(sink: object) -> BytesSink | None:
    """``sink`` when it records messages from their bytes alone (``BytesSink``), else None."""
    if isinstance(sink, BytesSink) and sink.records_bytes_only:
        return sink
    return None
