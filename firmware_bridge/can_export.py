"""A recorded run's ``can/frames`` as a CAN log file that python-can's tools read and replay.

The default is the candump log format as python-can writes it (``CanutilsLogWriter``; read back with
``can.CanutilsLogReader``, replayed with ``python -m can.player``). Other suffixes python-can writes
(``.asc``, ``.blf``, ``.trc``, ``.csv``) go through ``can.Logger``; ``.csv`` has no direction column
(python-can's format), so an export with sent frames warns that they read back as received. Frame times
keep the recorded spacing, so a replay does too; they are dated by the recording's wall-clock start when
it has one (``firmware_bridge.can_log_dates``: Unix time), else they are the recording's log times, with
.asc / .trc / .blf dated at export (and the header saying so) instead of 1970.

A record that does not describe a frame (bad hex, DLC disagreeing with the payload, id out of range) is
skipped, counted in ``ExportStats.rejected`` and logged; it never stops the export. A recording cut short
or damaged partway is exported up to that point, and ``ExportStats.stop`` says where (``logs.read_stop``):
the log holds what was recorded, and the caller says it is not all. A file with no recording in it (empty,
or not MCAP) is an error, and no log is written.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import can

from firmware_bridge.can_log_dates import DatedAscWriter, DatedTrcWriter, TimeBase, time_base
from firmware_bridge.errors import BridgeOperationError, BridgeSetupError, FrameError
from logs.errors import LogReadError
from logs.read_stop import ReadStop
from logs.reader import ReadStats, RecordedMessage, RecordedMetadata, Source, read_entries, topic_counts
from logs.topics import CAN_FRAMES
from logs.wall_clock import WALL_CLOCK_METADATA, WallClockAnchor

logger = logging.getLogger(__name__)

CANDUMP_SUFFIX = ".log"
# Formats python-can writes through ``can.Logger`` besides candump (chosen by the file suffix).
OTHER_SUFFIXES = (".asc", ".blf", ".trc", ".csv")
_STANDARD_ID_MAX = 0x7FF
_EXTENDED_ID_MAX = 0x1FFFFFFF
_CLASSIC_MAX_DLC = 8
# python-can's CSV columns are timestamp, id, extended, remote, error, dlc, data: no rx/tx, so its reader
# returns every frame as received.
_NO_DIRECTION_SUFFIXES = (".csv",)
# python-can's TRC writer has no error frame line: it logs "not implemented" and writes nothing, so the
# export leaves error records out of .trc itself, counted (ExportStats.error_frames_dropped) and said.
_NO_ERROR_FRAME_SUFFIXES = (".trc",)
_MAX_REJECTION_WARNINGS = 10  # the first few bad records are logged in full, the rest only counted


@dataclass
class ExportStats:
    """What one export wrote and skipped."""

    frames: int = 0
    tx: int = 0
    rx: int = 0
    # Of rx, the error frames the controller delivered (bus-off, restarted...), written as each format
    # writes one: candump a CAN_ERR_BUSERROR line and .asc an ErrorFrame line, both read back with id 0
    # (the class lost); .blf and .csv keep the class.
    error_frames: int = 0
    # Error frame records left out: the format has no line for them (.trc). Not in ``frames``.
    error_frames_dropped: int = 0
    rejected: int = 0  # records that do not describe a CAN frame
    first_ns: int | None = None
    last_ns: int | None = None
    truncated: bool = False  # the recording was cut short; everything before the cut was exported
    # Where the export stopped before the recording's end (a cut, or damage), else None.
    stop: ReadStop | None = None
    # The first frame's wall-clock time (ISO 8601, UTC) when the recording says when it ran; else None.
    wall_clock_start: str | None = None

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def record_to_message(record: dict[str, Any], log_time_ns: int, channel: str) -> can.Message:
    """One ``can/frames`` record as a python-can message stamped with its log time in seconds; a record
    marked ``"error": true`` as an error frame (its error class in the id, as python-can's socketcan
    delivers it). A record without the mark (every record made before error frames were recorded) is a
    data frame.

    Raises ``FrameError`` (reason ``record``) naming what is wrong with the record.
    """
    try:
        arbitration_id = record["id"]
        extended = record["extended"]
        dlc = record["dlc"]
        direction = record["direction"]
        data = bytes.fromhex(record["data"])
    except (KeyError, TypeError, ValueError) as err:
        raise FrameError(f"can/frames record is malformed: {err!r}", reason="record") from err
    error = record.get("error", False)
    if not isinstance(extended, bool) or not isinstance(error, bool) or direction not in ("tx", "rx"):
        raise FrameError(
            f"can/frames record has extended={extended!r}, error={error!r}, direction={direction!r}",
            reason="record",
        )
    # An error frame's id is its error class, of Linux's 29 bits (CAN_ERR_MASK) whatever its format.
    limit = _EXTENDED_ID_MAX if extended or error else _STANDARD_ID_MAX
    if not isinstance(arbitration_id, int) or not 0 <= arbitration_id <= limit:
        raise FrameError(f"can/frames record id {arbitration_id!r} is out of range", reason="record")
    if not isinstance(dlc, int) or dlc != len(data) or dlc > _CLASSIC_MAX_DLC:
        raise FrameError(
            f"can/frames record id 0x{arbitration_id:x}: dlc {dlc!r} does not match {len(data)} data bytes",
            reason="record",
            frame_id=arbitration_id,
        )
    return can.Message(
        timestamp=log_time_ns / 1e9,
        arbitration_id=arbitration_id,
        is_extended_id=extended,
        dlc=dlc,
        data=data,
        is_rx=direction == "rx",
        is_error_frame=error,
        channel=channel,
    )


def _check_suffix(output: Path) -> str:
    if output.is_dir():
        # The suffix would read as '' (or as a folder's own): what is wrong is that it names no file.
        raise BridgeSetupError(f"{output} is a folder: name the log file in it, e.g. {output / 'can.log'}")
    suffix = output.suffix.lower()
    if suffix != CANDUMP_SUFFIX and suffix not in OTHER_SUFFIXES:
        raise BridgeSetupError(
            f"{output}: unknown CAN log suffix {output.suffix!r}; use {CANDUMP_SUFFIX} (candump) or one of "
            f"{', '.join(OTHER_SUFFIXES)}"
        )
    return suffix


def _open_writer(output: Path, channel: str, base: TimeBase) -> can.Listener:
    suffix = output.suffix.lower()
    try:
        if suffix == CANDUMP_SUFFIX:
            return can.CanutilsLogWriter(output, channel=channel)
        if suffix == ".asc":
            return DatedAscWriter(output, base)
        if suffix == ".trc":
            return DatedTrcWriter(output, base)
        return can.Logger(output)
    except OSError as err:
        raise BridgeSetupError(f"cannot create {output}: {err}; check the folder") from err


def export_can_log(
    source: Source,
    output: str | Path,
    *,
    channel: str = "can0",
    wall_ns: Callable[[], int] = time.time_ns,
) -> ExportStats:
    """Write every ``can/frames`` record of the recording ``source`` to ``output`` (format by suffix).

    ``channel`` is the interface name written on each line (candump needs one; ``can0`` replays on the
    rover, ``vcan0`` on a HIL host). ``wall_ns`` (Unix ns) dates a log whose recording does not say when it
    ran (module docstring). Raises ``BridgeSetupError`` for an output it cannot create and
    ``BridgeOperationError`` for a recording it cannot read (missing, empty, not MCAP) or a whole one with no
    ``can/frames`` record (nothing is written); a recording cut short or damaged is exported up to that
    point (``stop``, ``truncated``), even if no frame came before it (an empty log).
    """
    if not channel or any(c.isspace() for c in channel):
        raise BridgeSetupError(f"CAN log channel must be a name without spaces, got {channel!r}")
    path = Path(output)
    suffix = _check_suffix(path)
    stats = ExportStats()
    read_stats = ReadStats()
    anchor: WallClockAnchor | None = None
    opened: tuple[TimeBase, can.Listener] | None = None  # from the first frame on
    try:
        entries = read_entries(
            source, topics=[CAN_FRAMES], stats=read_stats, stop_at_damage=True, refuse_empty=True
        )
        for entry in entries:
            if isinstance(entry, RecordedMetadata):
                # rover run writes it before any frame; one met later cannot re-date what is written.
                if entry.name == WALL_CLOCK_METADATA and opened is None:
                    anchor = WallClockAnchor.from_metadata(entry.data)
                continue
            if not isinstance(entry, RecordedMessage):
                continue
            try:
                msg = record_to_message(entry.message, entry.log_time_ns, channel)
            except FrameError as err:
                stats.rejected += 1
                if stats.rejected <= _MAX_REJECTION_WARNINGS:
                    logger.warning("skipped can/frames record at %d ns: %s", entry.log_time_ns, err)
                continue
            if msg.is_error_frame and suffix in _NO_ERROR_FRAME_SUFFIXES:
                stats.error_frames_dropped += 1
                continue
            if opened is None:
                # The writer opens at the first frame: only then is the file's date known.
                base = time_base(suffix, anchor, entry.log_time_ns, wall_ns())
                if base.from_recording:
                    stats.wall_clock_start = base.start.isoformat(timespec="microseconds")
                opened = base, _open_writer(path, channel, base)
            base, writer = opened
            msg.timestamp = base.stamp_s(entry.log_time_ns)
            writer.on_message_received(msg)
            stats.frames += 1
            if msg.is_rx:
                stats.rx += 1
                stats.error_frames += msg.is_error_frame
            else:
                stats.tx += 1
            if stats.first_ns is None:
                stats.first_ns = entry.log_time_ns
            stats.last_ns = entry.log_time_ns
    except LogReadError as err:
        raise BridgeOperationError(f"cannot export CAN frames: {err}") from err
    finally:
        if opened is not None:
            opened[1].stop()
    if opened is None and not stats.rejected and not stats.error_frames_dropped and read_stats.stop is None:
        # A whole recording with no frame record at all is the wrong file (the peer's truth.mcap, a
        # ground-station recording): an empty log and exit 0 would hide that.
        has = ""
        if isinstance(source, str | Path):  # a stream was read to its end: only a file is read again
            has = f" (it has {', '.join(topic_counts(source)) or 'no messages'})"
        raise BridgeOperationError(
            f"cannot export CAN frames: {source} has no {CAN_FRAMES} records{has}; the rover's recording "
            "holds them (a trial's trial.mcap, or rover run's), not the peer's truth.mcap"
        )
    if opened is None:  # cut short or damaged before its first frame, or only error frames .trc cannot
        # hold: the log is written, empty
        _open_writer(path, channel, time_base(suffix, anchor, 0, wall_ns())).stop()
    stats.truncated = read_stats.truncated
    stats.stop = read_stats.stop
    if suffix in _NO_DIRECTION_SUFFIXES and stats.tx:
        logger.warning(
            "%s: python-can's %s format has no direction column: the %d frames the companion sent read "
            "back as received; export to .log, .asc, .blf or .trc to keep the direction",
            path,
            suffix,
            stats.tx,
        )
    if stats.error_frames_dropped:
        logger.warning(
            "%s: python-can's %s format has no error frame line: the %d error frame(s) recorded (the "
            "controller's bus-off, restart...) are not in it; export to .blf or .csv to keep them with "
            "their class, .log or .asc to keep them without",
            path,
            suffix,
            stats.error_frames_dropped,
        )
    if stats.rejected > _MAX_REJECTION_WARNINGS:
        logger.warning("skipped %d can/frames records in all", stats.rejected)
    logger.info("exported %d CAN frames to %s", stats.frames, path)
    return stats
