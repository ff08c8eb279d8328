"""``rover logs recover``: turn a recording cut short (crash, power loss, full disk) into a valid MCAP file.

Everything complete before the cut is kept: every chunk that decompresses and passes its CRC, and every
top-level schema, channel, message, metadata and attachment record. A damaged chunk in the middle is
dropped and counted, and the copy goes on after it. Message bytes, log and publish times and sequence
numbers are copied unchanged; schema and channel ids are renumbered in the order first seen (the MCAP
writer assigns them), which readers never depend on. The output gets a fresh summary and footer.

A file with no message to keep (empty, cut inside its magic or header, cut before its first chunk's end,
every chunk damaged) is an error, ``NothingRecoverable``, and no output file is left behind: a
"recovered" MCAP of metadata and attachments alone would pass for a rescued recording (a trial writes
its metadata and attachments first, so a file cut before its first chunk's end holds those and nothing
else). The output is written beside ``output`` under a temporary name and renamed when complete, so a
failed recover neither leaves a file nor replaces one already there.

The writer chunks the messages anew (by size, not by the recorder's second of log time), so the output
has other chunks than the source: the result counts both (``chunks_kept`` read, ``chunks_written``).
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Callable
from dataclasses import asdict, dataclass
from io import BytesIO
from pathlib import Path
from typing import Any, BinaryIO

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Attachment, Channel, Header, Message, Metadata, Schema
from mcap.writer import CompressionType, Writer

from logs.errors import LogReadError, RecordingError
from logs.frames import Frame, FrameWalk, attachment_crc_ok, chunk_of, chunk_payload, inner_frames
from logs.recorder import DEFAULT_CHUNK_SIZE

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class RecoverResult:
    source: str
    output: str
    was_complete: bool  # the source had its DataEnd: nothing needed recovering
    cut_at: int | None
    chunks_kept: int  # chunks of the source whose records were copied
    chunks_written: int  # chunks of the output (the writer chunks anew: not chunks_kept)
    chunks_dropped: int
    messages: int
    orphan_messages: int  # messages whose channel record was lost; they cannot be decoded and are dropped
    metadata: int
    attachments: int
    first_ns: int | None
    last_ns: int | None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class NothingRecoverable(LogReadError):
    """The file holds no complete message: there is nothing to keep (metadata and attachments alone would
    pass for a rescued recording)."""


def recover(source: str | Path, output: str | Path) -> RecoverResult:
    """Copy every complete record of ``source`` into a new, valid MCAP file at ``output``;
    ``NothingRecoverable`` (and no output) when the file holds no message to keep."""
    src, dst = Path(source), Path(output)
    if src.resolve() == dst.resolve():
        raise RecordingError(f"recover writes a new file: give an output path other than {src}")
    if dst.is_dir():
        # Said at once: the copy goes to a temporary name first and would only fail at its rename.
        raise RecordingError(
            f"{dst} is a folder: give recover a file path for its output, e.g. {dst / src.name}"
        )
    try:
        stream = src.open("rb")
    except OSError as err:
        raise LogReadError(f"cannot open recording {src}: {err}") from err
    output_file = _LazyOutput(dst)
    with stream:
        copier = _Copier(output_file.writer)
        walk = FrameWalk(stream, str(src))
        try:
            copier.copy(walk)
        except BaseException:
            output_file.close(finish=False)
            output_file.remove()
            raise
    if copier.messages == 0:
        output_file.close(finish=False)
        output_file.remove()
        raise NothingRecoverable(
            f"nothing recoverable in {src}: {_why_no_message(copier, walk)}; no output written"
        )
    output_file.close(finish=True)
    chunks_written = output_file.commit()
    result = RecoverResult(
        source=str(src),
        output=str(dst),
        was_complete=copier.complete,
        cut_at=walk.cut_at,
        chunks_kept=copier.chunks_kept,
        chunks_written=chunks_written,
        chunks_dropped=copier.chunks_dropped,
        messages=copier.messages,
        orphan_messages=copier.orphans,
        metadata=copier.metadata,
        attachments=copier.attachments,
        first_ns=copier.first_ns,
        last_ns=copier.last_ns,
    )
    logger.info("recovered %s -> %s: %s", src, dst, result)
    return result


def _why_no_message(copier: _Copier, walk: FrameWalk) -> str:
    """Why a file gave no message: where it is cut or what was damaged, and what it held besides."""
    if walk.stop is not None and copier.chunks_kept == 0 and copier.chunks_dropped == 0:
        why = f"{walk.stop.describe()}, before its first chunk's end: no complete chunk"
    elif copier.chunks_kept == 0 and copier.chunks_dropped:
        why = f"no complete chunk: {copier.chunks_dropped} damaged chunk(s) dropped"
        if walk.stop is not None:
            why += f", then {walk.stop.describe()}"
    elif copier.orphans:
        where = f" (in the {copier.chunks_dropped} damaged chunk(s) dropped)" if copier.chunks_dropped else ""
        why = f"{copier.orphans} message(s) whose channel record was lost{where}, which cannot be decoded"
    else:
        why = "the recording holds none"
    if copier.metadata + copier.attachments:
        held = f"{copier.metadata} metadata and {copier.attachments} attachment record(s)"
        why += f"; its {held} alone are no recording"
    return f"no message ({why})"


class _LazyOutput:
    """The output file, created only when the first record worth copying arrives, under a temporary name
    beside ``path`` until ``commit`` (so a file with nothing to keep neither creates nor replaces
    anything)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.partial = path.with_name(path.name + ".partial")
        self._stream: BinaryIO | None = None
        self._writer: Writer | None = None

    def writer(self) -> Writer:
        if self._writer is None:
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                self._stream = self.partial.open("wb")
            except OSError as err:
                raise RecordingError(f"cannot create {self.partial}: {err}") from err
            self._writer = Writer(
                self._stream, chunk_size=DEFAULT_CHUNK_SIZE, compression=CompressionType.ZSTD
            )
        return self._writer

    def close(self, *, finish: bool) -> None:
        if self._writer is not None and finish:
            self._writer.finish()
        if self._stream is not None:
            self._stream.close()

    def remove(self) -> None:
        if self._stream is not None:  # only a file this run created
            self.partial.unlink(missing_ok=True)

    def commit(self) -> int:
        """Give the finished file its name; the number of chunks written (from its summary, as ``rover
        logs doctor`` counts them)."""
        try:
            with self.partial.open("rb") as written:
                summary = make_reader(written).get_summary()
            self.partial.replace(self.path)
        except OSError as err:
            self.remove()
            raise RecordingError(f"cannot write {self.path}: {err}") from err
        return 0 if summary is None or summary.statistics is None else summary.statistics.chunk_count


class _Copier:
    def __init__(self, open_writer: Callable[[], Writer]) -> None:
        self._open_writer = open_writer
        self.writer: Writer | None = None
        self.header: tuple[str, str] = ("", "")
        self.started = False
        self.complete = False
        self.schema_ids: dict[int, int] = {0: 0}  # schema id 0 means "no schema" in MCAP
        self.channel_ids: dict[int, int] = {}
        self.chunks_kept = self.chunks_dropped = 0
        self.messages = self.orphans = self.metadata = self.attachments = 0
        self.first_ns: int | None = None
        self.last_ns: int | None = None

    def copy(self, walk: FrameWalk) -> None:
        for frame in walk.frames():
            if frame.opcode == Opcode.DATA_END:
                self.complete = True
                break
            try:
                self._frame(frame)
            except (McapError, ValueError, struct.error, UnicodeDecodeError) as err:
                logger.warning(
                    "record at byte %d (opcode %#x) is damaged, skipped: %s", frame.offset, frame.opcode, err
                )

    def _out(self) -> Writer:
        """The output, opened and started on the first record to copy (with the source's header)."""
        if self.writer is None:
            self.writer = self._open_writer()
            profile, library = self.header
            self.writer.start(profile=profile, library=library or "rover-stack logs (recovered)")
            self.started = True
        return self.writer

    def _frame(self, frame: Frame) -> None:
        data = ReadDataStream(BytesIO(frame.body))
        if frame.opcode == Opcode.HEADER:
            header = Header.read(data)
            self.header = (header.profile, header.library)
            return
        if frame.opcode == Opcode.CHUNK:
            self._chunk(frame)
        elif frame.opcode in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE):
            self._record(frame.opcode, frame.body)
        elif frame.opcode == Opcode.METADATA:
            metadata = Metadata.read(data)
            self._out().add_metadata(metadata.name, dict(metadata.metadata))
            self.metadata += 1
        elif frame.opcode == Opcode.ATTACHMENT:
            if not attachment_crc_ok(frame.body):
                raise ValueError("attachment fails its CRC check")
            attachment = Attachment.read(data)
            self._out().add_attachment(
                create_time=attachment.create_time,
                log_time=attachment.log_time,
                name=attachment.name,
                media_type=attachment.media_type,
                data=attachment.data,
            )
            self.attachments += 1

    def _chunk(self, frame: Frame) -> None:
        try:
            records = list(inner_frames(chunk_payload(chunk_of(frame))))
        except ValueError as err:
            self.chunks_dropped += 1
            logger.warning("chunk at byte %d dropped: %s", frame.offset, err)
            return
        for opcode, body in records:
            self._record(opcode, body)
        self.chunks_kept += 1

    def _record(self, opcode: int, body: bytes) -> None:
        data = ReadDataStream(BytesIO(body))
        if opcode == Opcode.SCHEMA:
            schema = Schema.read(data)
            if schema.id not in self.schema_ids:
                self.schema_ids[schema.id] = self._out().register_schema(
                    schema.name, schema.encoding, schema.data
                )
        elif opcode == Opcode.CHANNEL:
            channel = Channel.read(data)
            if channel.id not in self.channel_ids:
                schema_id = self.schema_ids.get(channel.schema_id, 0)
                self.channel_ids[channel.id] = self._out().register_channel(
                    channel.topic, channel.message_encoding, schema_id, dict(channel.metadata)
                )
        elif opcode == Opcode.MESSAGE:
            message = Message.read(data, len(body))
            channel_id = self.channel_ids.get(message.channel_id)
            if channel_id is None:
                self.orphans += 1
                return
            self._out().add_message(
                channel_id=channel_id,
                log_time=message.log_time,
                data=message.data,
                publish_time=message.publish_time,
                sequence=message.sequence,
            )
            self.messages += 1
            t = message.log_time
            self.first_ns = t if self.first_ns is None else min(self.first_ns, t)
            self.last_ns = t if self.last_ns is None else max(self.last_ns, t)
