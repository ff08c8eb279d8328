"""Dates for exported CAN logs: the recording's wall-clock start, else the export time and a note saying so.

A recording stamps frames with the run's clock (monotonic or simulated: no date). Written as they are,
python-can's .asc / .trc / .blf writers date the file by the first frame's stamp: 1970. With the recording's
``wall_clock`` anchor (``logs.wall_clock``, written by ``rover run``) every frame is stamped in Unix time.
Without one (a lockstep trial), .asc / .trc / .blf, which store times from the first frame, are dated at
export instead, and .asc / .trc say so in a header comment; .log / .csv keep the recording's own times.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TextIO

import can

from logs.clock import NS_PER_S
from logs.wall_clock import WallClockAnchor

# Formats that store each frame's time from the first one and date the file by the first frame.
RELATIVE_SUFFIXES = (".asc", ".trc", ".blf")


@dataclass(frozen=True)
class TimeBase:
    """How log times become the stamps written: ``stamp = log time + offset_ns``; ``start`` (UTC) is the
    first frame's date in the file, from the recording (``from_recording``) or the time of export."""

    offset_ns: int
    start: datetime
    from_recording: bool

    def stamp_s(self, log_time_ns: int) -> float:
        return (log_time_ns + self.offset_ns) / NS_PER_S

    @property
    def note(self) -> str:
        """One line for the header: where the date comes from."""
        when = self.start.isoformat(timespec="milliseconds")
        if self.from_recording:
            return f"start {when}: the recording's wall-clock start (its wall_clock metadata)"
        return (
            f"the recording holds no wall-clock start (lockstep trials run on simulated time): dated at "
            f"export, {when}; frame times count from the first frame"
        )


def time_base(
    suffix: str, anchor: WallClockAnchor | None, first_log_ns: int, export_unix_ns: int
) -> TimeBase:
    """The time base for a log of ``suffix`` whose first frame was logged at ``first_log_ns``."""
    if anchor is not None:
        first = anchor.unix_ns_at(first_log_ns)
        return TimeBase(anchor.unix_ns - anchor.clock_ns, _utc(first), from_recording=True)
    if suffix.lower() in RELATIVE_SUFFIXES:
        return TimeBase(export_unix_ns - first_log_ns, _utc(export_unix_ns), from_recording=False)
    return TimeBase(0, _utc(export_unix_ns), from_recording=False)


def _utc(unix_ns: int) -> datetime:
    return datetime.fromtimestamp(unix_ns / NS_PER_S, UTC)


class DatedAscWriter(can.ASCWriter):
    """python-can's ASC writer with both header dates set to ``base.start`` and a comment saying why.

    python-can dates the ``date`` line with the time of writing and ``Begin Triggerblock`` with the first
    frame's stamp; both go through ``_format_header_datetime``, so that is where the start is put in.
    """

    def __init__(self, file: str | Path | TextIO, base: TimeBase) -> None:
        self._start = base.start.astimezone()  # ASC dates are local time, as python-can writes them
        super().__init__(file)
        self.file.write(f"// {base.note}\n")  # where a Vector log keeps its "// version" comment

    def _format_header_datetime(self, dt: datetime) -> str:
        del dt
        return str(super()._format_header_datetime(self._start))


class DatedTrcWriter(can.TRCWriter):
    """python-can's TRC writer (dated by the first frame's stamp) with a header comment saying why."""

    def __init__(self, file: str | Path | TextIO, base: TimeBase) -> None:
        super().__init__(file)
        self._note = base.note

    def write_header(self, timestamp: float) -> None:
        super().write_header(timestamp)
        self.file.write(f";   {self._note}\n")
