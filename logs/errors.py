"""The error family of ``logs``: one base, then one class per thing that can go wrong.

Messages say what failed and what to do about it; the original exception rides along as ``__cause__``.
"""

from __future__ import annotations

from logs.read_stop import ReadStop


class LogsError(Exception):
    """Base of every error raised by the ``logs`` package."""


class RecordingError(LogsError):
    """Writing an MCAP recording failed: unknown topic, unencodable message, closed recorder, I/O error."""


class LogReadError(LogsError):
    """A recording cannot be read: the file is missing, unreadable, not MCAP, or damaged inside.

    A file merely cut short (a crash while recording) is *not* an error: readers return the complete
    prefix and log a warning.
    """


class NotARecording(LogReadError):
    """The file holds no MCAP recording at all: it starts with other bytes, or (for tools that refuse it)
    it is empty or ends inside the MCAP magic."""


class RecordingDamaged(LogReadError):
    """A complete record of the recording does not parse (a flipped bit, a chunk failing its CRC);
    ``stop`` says where, for a tool that keeps what it read before it."""

    def __init__(self, name: str, stop: ReadStop) -> None:
        super().__init__(f"{name} is {stop.describe()}")
        self.stop = stop


class TelemetryError(LogsError):
    """The live Zenoh telemetry stream failed while running."""


class TelemetrySetupError(TelemetryError):
    """The Zenoh telemetry stream could not be configured or opened."""
