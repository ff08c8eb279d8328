"""The onboard stack's warnings on the recording's ``log`` topic, so an analyst sees them afterwards.

Without this, an estimator warning ("wheels spinning in place", "GPS gated out for 10 s") reached stderr
only, and the recording's ``log`` topic held nothing but the simulator's fault lines. ``recording_logs``
attaches a ``LogTopicHandler`` to the onboard packages' loggers (estimator, navigator: guidance and
safety, firmware_bridge: the links) for as long as a lockstep trial or ``rover run`` records.

Floods are cut: the same line (digits aside: "rejected a sample (gps_gated, 100 so far)" is the same line
as "... 200 so far") is recorded at most ``burst`` times per ``window_s`` of the clock; what was left out
is counted, and the next line of that kind that gets through says how many, as does ``close()``.

Recorders here are single-threaded (``logs.pending_sink``): a line logged on another thread (the
planning worker's) is formatted there, on the thread that logged it (its arguments may change later),
queued, and published on the recording thread by ``publish_pending`` or the next line logged there.
Nothing a handler does may raise into the code that logged: a line that cannot be formatted is recorded
as its raw text, anything else that fails is counted in ``failed``.
"""

from __future__ import annotations

import logging
import re
import threading
from collections import deque
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

from logs import topics
from logs.clock import Clock, to_ns
from logs.sink import MessageSink

# The onboard stack's packages: estimator, guidance and safety (navigator), links (firmware_bridge).
ONBOARD_LOGGERS = ("estimator", "navigator", "firmware_bridge")
# Python logging levels as Foxglove's (logs.topics LOG_*).
_FOXGLOVE_LEVELS = (
    (logging.CRITICAL, topics.LOG_FATAL),
    (logging.ERROR, topics.LOG_ERROR),
    (logging.WARNING, topics.LOG_WARNING),
    (logging.INFO, topics.LOG_INFO),
)
_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def foxglove_level(levelno: int) -> int:
    """A Python logging level as Foxglove's ``Log.level``."""
    for threshold, level in _FOXGLOVE_LEVELS:
        if levelno >= threshold:
            return level
    return topics.LOG_DEBUG


@dataclass(frozen=True)
class _Line:
    """A log record as text, taken on the thread that logged it."""

    t_ns: int
    levelno: int
    name: str
    message: str
    pathname: str
    lineno: int


def _text(record: logging.LogRecord) -> str:
    """The record's message; a call with the wrong arguments (or one whose ``__str__`` raises) still
    leaves a line: its raw text and why it could not be formatted."""
    try:
        return record.getMessage()
    except Exception as err:
        return f"{record.msg!r} (unformattable: {type(err).__name__}: {err})"


@dataclass
class _Kind:
    """One kind of line (its text with the numbers blanked) within the current rate window."""

    window_start_ns: int
    recorded: int = 0
    suppressed: int = 0
    example: str = ""


class LogTopicHandler(logging.Handler):
    """Publishes log records on ``log`` through ``sink``, stamped by ``clock``, floods cut.

    Parameters
    ----------
    sink : MessageSink
        Where the lines go (the recording, possibly fanned out to telemetry).
    clock : Clock
        Source of each line's ``log_time`` and of the rate window.
    level : int
        Lowest level recorded (default WARNING: the onboard stack's INFO lines are for the console).
    burst : int
        Lines of one kind recorded per window before the rest are only counted.
    window_s : float
        Length of the rate window, seconds of ``clock``.
    """

    def __init__(
        self,
        sink: MessageSink,
        clock: Clock,
        *,
        level: int = logging.WARNING,
        burst: int = 5,
        window_s: float = 10.0,
    ) -> None:
        if burst < 1 or not window_s > 0.0:
            raise ValueError(f"LogTopicHandler needs burst >= 1 and window_s > 0, got {burst}, {window_s}")
        super().__init__(level)
        self._sink = sink
        self._clock = clock
        self._burst = burst
        self._window_ns = to_ns(window_s)
        self._owner = threading.get_ident()
        self._queued: deque[_Line] = deque()  # from other threads
        self._kinds: dict[str, _Kind] = {}
        self._publishing = False
        self.published = 0
        self.suppressed = 0
        self.failed = 0  # lines the sink refused (counted, not logged: that would log about logging)

    def emit(self, record: logging.LogRecord) -> None:
        try:
            line = _Line(self._clock.now_ns(), record.levelno, record.name, _text(record), record.pathname,
                         record.lineno)  # fmt: skip
            if threading.get_ident() != self._owner:
                self._queued.append(line)  # deque.append is atomic
                return
            if self._publishing:
                return  # a line logged by the sink while it records a line: never recursive
            self.publish_pending()
            self._record(line)
        except Exception:  # a logging handler must never raise into the code that logged
            self.failed += 1

    def publish_pending(self) -> None:
        """Publish what other threads logged (call on the recording thread, e.g. once per tick)."""
        while self._queued:
            line = self._queued.popleft()
            try:
                self._record(line)
            except Exception:  # the loop thread calls this: a bad line must not stop it
                self.failed += 1

    def close(self) -> None:
        """Publish the queue and, per kind of line still being cut, how many were left out."""
        if threading.get_ident() == self._owner:
            self.publish_pending()
            now = self._clock.now_ns()
            for kind in self._kinds.values():
                if kind.suppressed:
                    left_out = f"{kind.suppressed} more like: {kind.example}"
                    self._publish(now, topics.LOG_WARNING, __name__, left_out)
                    kind.suppressed = 0
        super().close()

    def _record(self, line: _Line) -> None:
        now, message = line.t_ns, line.message
        key = f"{line.name}:{_NUMBER.sub('#', message)}"
        kind = self._kinds.get(key)
        if kind is None or now - kind.window_start_ns >= self._window_ns:
            kind = self._kinds[key] = (
                _Kind(now) if kind is None else _Kind(now, suppressed=kind.suppressed, example=kind.example)
            )
        if kind.recorded >= self._burst:
            kind.suppressed += 1
            kind.example = message
            self.suppressed += 1
            return
        kind.recorded += 1
        if kind.suppressed:
            message = f"{message} ({kind.suppressed} similar lines left out before this one)"
            kind.suppressed = 0
        self._publish(now, foxglove_level(line.levelno), line.name, message, line)

    def _publish(self, now: int, level: int, name: str, message: str, line: _Line | None = None) -> None:
        self._publishing = True
        try:
            file, lineno = ("", 0) if line is None else (line.pathname, line.lineno)
            self._sink.publish(topics.LOG, now, topics.log_message(now, level, name, message, file, lineno))
            self.published += 1
        except Exception:  # a logging handler must never raise into the code that logged
            self.failed += 1
        finally:
            self._publishing = False


@contextmanager
def recording_logs(
    sink: MessageSink, clock: Clock, loggers: Sequence[str] = ONBOARD_LOGGERS
) -> Iterator[LogTopicHandler]:
    """Within the block, WARNING+ lines of ``loggers`` also go to ``sink``'s ``log`` topic (they still
    reach the console as before); the handler is detached and closed after."""
    handler = LogTopicHandler(sink, clock)
    attached = [logging.getLogger(name) for name in loggers]
    for logger in attached:
        logger.addHandler(handler)
    try:
        yield handler
    finally:
        for logger in attached:
            logger.removeHandler(handler)
        handler.close()
