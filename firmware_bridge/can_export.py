"""A recorded run's ``can/frames`` as a CAN log file that python-can's tools read and replay.

The default is the candump log format as python-can writes it (``CanutilsLogWriter``; read back with
``can.CanutilsLogReader``, replayed with ``python -m can.player``). Other suffixes python-can writes
(``.asc``, ``.blf``, ``.trc``, ``.csv``) go through ``can.Logger``. Frame times are the recording's log
times (the rover's clock: simulated seconds in lockstep runs), so a replay keeps the recorded spacing.

A record that does not describe a frame (bad hex, DLC disagreeing with the payload, id out of range) is
skipped, counted in ``ExportStats.rejected`` and logged; it never stops the export.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import can

from firmware_bridge.errors import BridgeOperationError, BridgeSetupError, FrameError
from logs.errors import LogReadError
from logs.reader import ReadStats, Source, read_messages
from logs.topics import CAN_FRAMES

logger = logging.getLogger(__name__)

CANDUMP_SUFFIX = ".log"
# Formats python-can writes through ``can.Logger`` besides candump (chosen by the file suffix).
OTHER_SUFFIXES = (".asc", ".blf", ".trc", ".csv")
_STANDARD_ID_MAX = 0x7FF
_EXTENDED_ID_MAX = 0x1FFFFFFF
_CLASSIC_MAX_DLC = 8
_MAX_REJECTION_WARNINGS = 10  # the first few bad records are logged in full, the rest only counted


@dataclass
class ExportStats:
    """What one export wrote and skipped."""

    frames: int = 0
    tx: int = 0
    rx: int = 0
    rejected: int = 0  # records that do not describe a CAN frame
    first_ns: int | None = None
    last_ns: int | None = None
    truncated: bool = False  # the recording was cut short; everything before the cut was exported

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def record_to_message(record: dict[str, Any], log_time_ns: int, channel: str) -> can.Message:
    """One ``can/frames`` record as a python-can message stamped with its log time in seconds.

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
    if not isinstance(extended, bool) or direction not in ("tx", "rx"):
        raise FrameError(
            f"can/frames record has extended={extended!r}, direction={direction!r}", reason="record"
        )
    limit = _EXTENDED_ID_MAX if extended else _STANDARD_ID_MAX
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
        channel=channel,
    )


def _open_writer(output: Path, channel: str) -> can.Listener:
    suffix = output.suffix.lower()
    try:
        if suffix == CANDUMP_SUFFIX:
            return can.CanutilsLogWriter(output, channel=channel)
        if suffix in OTHER_SUFFIXES:
            return can.Logger(output)
    except OSError as err:
        raise BridgeSetupError(f"cannot create {output}: {err}; check the folder") from err
    raise BridgeSetupError(
        f"{output}: unknown CAN log suffix {output.suffix!r}; use {CANDUMP_SUFFIX} (candump) or one of "
        f"{', '.join(OTHER_SUFFIXES)}"
    )


def export_can_log(source: Source, output: str | Path, *, channel: str = "can0") -> ExportStats:
    """Write every ``can/frames`` record of the recording ``source`` to ``output`` (format by suffix).

    ``channel`` is the interface name written on each line (candump needs one; ``can0`` replays on the
    rover, ``vcan0`` on a HIL host). Raises ``BridgeSetupError`` for an output it cannot create and
    ``BridgeOperationError`` for a recording it cannot read; a recording cut short is exported up to the
    cut (``truncated``).
    """
    if not channel or any(c.isspace() for c in channel):
        raise BridgeSetupError(f"CAN log channel must be a name without spaces, got {channel!r}")
    path = Path(output)
    stats = ExportStats()
    read_stats = ReadStats()
    writer = _open_writer(path, channel)
    try:
        for recorded in read_messages(source, topics=[CAN_FRAMES], stats=read_stats):
            try:
                msg = record_to_message(recorded.message, recorded.log_time_ns, channel)
            except FrameError as err:
                stats.rejected += 1
                if stats.rejected <= _MAX_REJECTION_WARNINGS:
                    logger.warning("skipped can/frames record at %d ns: %s", recorded.log_time_ns, err)
                continue
            writer.on_message_received(msg)
            stats.frames += 1
            if msg.is_rx:
                stats.rx += 1
            else:
                stats.tx += 1
            if stats.first_ns is None:
                stats.first_ns = recorded.log_time_ns
            stats.last_ns = recorded.log_time_ns
    except LogReadError as err:
        raise BridgeOperationError(f"cannot export CAN frames: {err}") from err
    finally:
        writer.stop()
    stats.truncated = read_stats.truncated
    if stats.rejected > _MAX_REJECTION_WARNINGS:
        logger.warning("skipped %d can/frames records in all", stats.rejected)
    logger.info("exported %d CAN frames to %s", stats.frames, path)
    return stats
