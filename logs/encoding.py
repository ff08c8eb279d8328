"""The bytes of a recorded or streamed message: compact JSON, NaN and infinity as ``null``.

The MCAP recorder and the Zenoh stream carry exactly these bytes, so a ``FanoutSink`` encodes each message
once and hands the same bytes to every sink that takes them (``EncodedSink``).

This sits on the lockstep trial's hot path (~1300 messages per simulated second), so the common case is
one call into the C encoder built once for the process. ``json.dumps`` would build a new encoder object
for every call because our separators are not its defaults; both give the same bytes (a test checks).
"""

from __future__ import annotations

import json
import json.encoder
import math
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

# The same alias as logs.sink.Message (which imports this module, so it cannot be imported from there).
Message = dict[str, Any]
_SEPARATORS = (",", ":")


def _json_default(value: Any) -> Any:
    # numpy scalars and arrays have tolist(); anything else is a caller bug worth a clear error.
    tolist = getattr(value, "tolist", None)
    if tolist is not None:
        return tolist()
    raise TypeError(f"{type(value).__name__} value {value!r} is not JSON-serialisable")


def _build_encoder() -> Callable[[Any], str]:
    """One reusable encoder: the C one when this Python has it, else the pure-Python ``JSONEncoder``."""
    make = getattr(json.encoder, "c_make_encoder", None)
    if make is None:
        return json.JSONEncoder(separators=_SEPARATORS, allow_nan=False, default=_json_default).encode
    # markers=None: no circular-reference bookkeeping. A dict of markers kept across calls would keep
    # stale entries after a failed call; a cycle ends in RecursionError instead, reported as ValueError.
    iterencode = make(
        None,  # markers
        _json_default,
        json.encoder.encode_basestring_ascii,  # ensure_ascii=True, as json.dumps
        None,  # indent
        _SEPARATORS[1],  # key separator
        _SEPARATORS[0],  # item separator
        False,  # sort_keys
        False,  # skipkeys
        False,  # allow_nan
    )

    def encode(value: Any) -> str:
        return "".join(iterencode(value, 0))

    return encode


_encode = _build_encoder()


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


def encode_message(message: Message) -> bytes:
    """Compact JSON bytes of ``message``; NaN and +/-inf become ``null`` (JSON has no NaN).

    The common case is a single encoder call. Only a message holding a non-finite float pays for a
    second pass. Raises ``TypeError`` for values JSON cannot hold and ``ValueError`` for circular data.
    """
    try:
        return _encode(message).encode()
    except ValueError:
        pass  # a non-finite float (or a cycle in the fallback encoder, which the second pass reports)
    except RecursionError as err:
        raise ValueError("message is circular or nested too deeply to encode as JSON") from err
    try:
        repaired = _finite(message)
    except RecursionError as err:
        raise ValueError("message is circular or nested too deeply to encode as JSON") from err
    return _encode(repaired).encode()


@runtime_checkable
class EncodedSink(Protocol):
    """A sink that can take a message's bytes from ``encode_message`` instead of encoding it again.

    ``data`` is exactly ``encode_message(message)``; ``message`` rides along for sinks that look inside
    (a rate limiter in front of a publisher does not, but a test double may).
    """

    def publish(self, topic: str, log_time_ns: int, message: Message) -> None: ...

    def publish_encoded(self, topic: str, log_time_ns: int, message: Message, data: bytes) -> None: ...
