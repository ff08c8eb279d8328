"""Reading MCAP recordings, including files cut short by a crash or a full disk.

The reader walks the data section front to back and never seeks, so it reads a file that is still being
written, a pipe, or a file whose summary and footer were never written. Record framing (opcode + length)
is read here so that a cut is told apart from damage: a record whose bytes end early is the cut (stop,
warn, keep everything before it); a record that is complete but does not parse is damage
(``RecordingDamaged``, or with ``stop_at_damage`` a stop like the cut's, for tools that keep what they read).
Either way ``ReadStats.stop`` says where (``logs.read_stop``). Record bodies are parsed with the ``mcap``
library's record classes.

Only our own recordings are in scope: JSON messages (``logs.recorder``). A message whose payload is not a
JSON object is skipped and counted in ``ReadStats``, never raised.
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Callable, Collection, Iterator
from contextlib import ExitStack
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import Any, BinaryIO, TypeVar

from fastcrc import crc32
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Chunk, McapRecord, Message, Metadata

from logs.chunk_codec import UnsupportedCompression, decompress
from logs.chunk_kernel import LAYOUT_CUT_BODY, LAYOUT_CUT_HEAD, chunk_layout, skip_mask
from logs.errors import LogReadError, RecordingDamaged
from logs.frames import MAX_RECORD_BYTES, MCAP_MAGIC, magic_complete, oversized_record
from logs.json_text import loads_json
from logs.read_stop import CUT, DAMAGED, ReadStop

logger = logging.getLogger(__name__)

Source = str | Path | BinaryIO

_FRAME_HEAD = struct.Struct("<BQ")  # opcode uint8, record length uint64
_MESSAGE_HEAD = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time; then the data
# The message head's fields a reader uses: channel id and log time (sequence and publish time skipped).
_MESSAGE_KEY = struct.Struct("<H4xQ8x")
_READ_PIECE = 1 << 20  # read big records in pieces so memory follows the bytes really present
_MAX_WARNINGS = 10  # per read: the first few malformed messages are logged, the rest only counted


# slots: a reader builds one per message (~8,500 in a trial's metrics pass), and a frozen dataclass with
# slots is built ~25 % faster than one with a __dict__.
@dataclass(frozen=True, slots=True)
class RecordedMessage:
    topic: str
    log_time_ns: int
    message: dict[str, Any]


@dataclass(frozen=True)
class RecordedMetadata:
    name: str
    data: dict[str, str]


@dataclass(frozen=True)
class RecordedAttachment:
    name: str
    media_type: str
    log_time_ns: int
    data: bytes = field(repr=False)


@dataclass(frozen=True, slots=True)  # slots: one per message, as RecordedMessage
class RecordedRaw:
    """A message left undecoded (``raw_topics``): its payload bytes as recorded."""

    topic: str
    log_time_ns: int
    data: bytes


Entry = RecordedMessage | RecordedMetadata | RecordedAttachment | RecordedRaw

# A reader builds one RecordedMessage or RecordedRaw per message it hands over (~8,200 in a trial's metrics
# pass). A frozen dataclass's __init__, reached through the type's call, sets each field through
# object.__setattr__: ~3x the cost of setting its slots directly, as _entry does. It builds the same
# objects, still frozen to every other caller (tests/logs/test_recorder_reader.py).
_new_entry = object.__new__
_SlotSetter = Callable[[object, Any], None]
_SlotSetters = tuple[_SlotSetter, _SlotSetter, _SlotSetter]
_MESSAGE_SLOTS: _SlotSetters = tuple(
    vars(RecordedMessage)[name].__set__ for name in ("topic", "log_time_ns", "message")
)
_RAW_SLOTS: _SlotSetters = tuple(vars(RecordedRaw)[name].__set__ for name in ("topic", "log_time_ns", "data"))
_E = TypeVar("_E", RecordedMessage, RecordedRaw)


def _entry(kind: type[_E], slots: _SlotSetters, topic: str, log_time_ns: int, payload: Any) -> _E:
    """``kind(topic, log_time_ns, payload)``, its slots (``_MESSAGE_SLOTS``, ``_RAW_SLOTS``) set directly."""
    entry: _E = _new_entry(kind)
    set_topic, set_log_time, set_payload = slots
    set_topic(entry, topic)
    set_log_time(entry, log_time_ns)
    set_payload(entry, payload)
    return entry


# A message record as the framing hands it over: (channel id, log time ns, payload). A plain tuple, not the
# ``mcap`` package's ``Message``: a trial's metrics pass builds ~8,500 of them, and the sequence number and
# publish time that object would also hold are read by nobody here.
MessageRow = tuple[int, int, bytes]
RawRecord = McapRecord | MessageRow


@dataclass
class ReadStats:
    """What one read went through; pass one in to learn about skipped messages and cut files."""

    messages: int = 0
    malformed: int = 0  # payload not a JSON object
    unknown_channel: int = 0  # message on a channel whose record was never seen
    not_json: int = 0  # channel with another message encoding
    truncated: bool = False
    complete: bool = False  # the data section ended with its DataEnd record
    stop: ReadStop | None = None  # where a cut (or, with stop_at_damage, damage) ended the read early

    @property
    def skipped(self) -> int:
        return self.malformed + self.unknown_channel + self.not_json


# --- public readers ----------------------------------------------------------------------------
def read_entries(
    source: Source,
    *,
    topics: Collection[str] | None = None,
    messages: bool = True,
    stats: ReadStats | None = None,
    raw_topics: Collection[str] = (),
    stop_at_damage: bool = False,
    refuse_empty: bool = False,
    warn_cut: bool = True,
) -> Iterator[Entry]:
    """Messages, metadata and attachments in file order, in one pass.

    ``topics`` limits the messages to those topics; ``messages=False`` skips them all without
    decompressing chunks (fast for metadata and attachments). Messages on ``raw_topics`` come as
    ``RecordedRaw`` without JSON decoding (for analyses that only count or scan them). Raises
    ``LogReadError`` for a file that is missing or not MCAP (``NotARecording``) and ``RecordingDamaged``
    for damage; a cut file ends the iteration early with a warning (``stats.truncated``, ``stats.stop``).

    For tools whose output is what was read (exports): ``stop_at_damage`` ends the iteration at damage
    as at a cut (``stats.stop``) instead of raising; ``refuse_empty`` raises ``NotARecording`` for a file
    that ends before its magic is complete (empty: nothing to export) instead of reading it as cut.
    ``warn_cut=False``: no warning at a cut (a first look at a file that is read again, and warned of, next).
    """
    stats = stats if stats is not None else ReadStats()
    wanted = frozenset(topics) if topics is not None else None
    raw = frozenset(raw_topics)
    if wanted is not None:
        wanted |= raw
    channels: dict[int, Channel] = {}
    # Channels whose messages nobody asked for: a chunk's reader passes over them without a Message object.
    unwanted: set[int] = set()
    with ExitStack() as stack:
        stream, name = _open(source, stack)
        for record in _records(
            stream,
            name,
            stats,
            decode_chunks=messages,
            skip_channels=unwanted,
            stop_at_damage=stop_at_damage,
            refuse_empty=refuse_empty,
            warn_cut=warn_cut,
        ):
            if type(record) is tuple:  # a MessageRow: the hot path, first
                if messages:
                    decoded = _decode(record, channels, wanted, stats, name, raw)
                    if decoded is not None:
                        yield decoded
            elif isinstance(record, Channel):
                channels[record.id] = record
                if wanted is not None and record.topic not in wanted:
                    unwanted.add(record.id)
            elif isinstance(record, Metadata):
                yield RecordedMetadata(record.name, dict(record.metadata))
            elif isinstance(record, Attachment):
                yield RecordedAttachment(record.name, record.media_type, record.log_time, record.data)


def read_messages(
    source: Source, topics: Collection[str] | None = None, *, stats: ReadStats | None = None
) -> Iterator[RecordedMessage]:
    """Decoded messages in file order (log-time order within our recordings)."""
    for entry in read_entries(source, topics=topics, stats=stats):
        if isinstance(entry, RecordedMessage):
            yield entry


def read_metadata(source: Source, *, warn_cut: bool = True) -> dict[str, dict[str, str]]:
    """Metadata records by name; a later record of the same name replaces an earlier one. ``warn_cut`` as
    for ``read_entries``."""
    return {
        entry.name: entry.data
        for entry in read_entries(source, messages=False, warn_cut=warn_cut)
        if isinstance(entry, RecordedMetadata)
    }


def read_attachments(source: Source) -> dict[str, bytes]:
    """Attachment contents by name; a later attachment of the same name replaces an earlier one."""
    return {
        entry.name: entry.data
        for entry in read_entries(source, messages=False)
        if isinstance(entry, RecordedAttachment)
    }


@dataclass(frozen=True)
class RecordingOutline:
    """What a recording is, read without its messages: its metadata and the span of its log times."""

    metadata: dict[str, dict[str, str]]
    span_ns: tuple[int, int] | None  # first and last message log time; None: it holds no message


def read_outline(source: Source, *, warn_cut: bool = True) -> RecordingOutline:
    """Metadata (a later record of a name replaces an earlier one) and the messages' log-time span, from
    the chunk headers: no chunk is decompressed, so it costs little more than reading the bytes. A cut
    file: what comes before the cut. ``LogReadError`` and ``warn_cut`` as for ``read_entries``."""
    metadata: dict[str, dict[str, str]] = {}
    spans: list[tuple[int, int]] = []
    with ExitStack() as stack:
        stream, name = _open(source, stack)
        records = _records(
            stream, name, ReadStats(), decode_chunks=False, chunk_headers=True, warn_cut=warn_cut
        )
        for record in records:
            if isinstance(record, Chunk):
                spans.append((record.message_start_time, record.message_end_time))
            elif type(record) is tuple:  # a message outside any chunk (an unchunked recording)
                _, log_time, _ = record
                spans.append((log_time, log_time))
            elif isinstance(record, Metadata):
                metadata[record.name] = dict(record.metadata)
    span = (min(s[0] for s in spans), max(s[1] for s in spans)) if spans else None
    return RecordingOutline(metadata, span)


def topic_counts(
    source: Source,
    *,
    stats: ReadStats | None = None,
    stop_at_damage: bool = False,
    refuse_empty: bool = False,
) -> dict[str, int]:
    """Number of messages per topic (payloads are not decoded), sorted by topic; the keywords as for
    ``read_entries``."""
    counts: dict[str, int] = {}
    channels: dict[int, str] = {}
    with ExitStack() as stack:
        stream, name = _open(source, stack)
        records = _records(
            stream,
            name,
            stats if stats is not None else ReadStats(),
            decode_chunks=True,
            stop_at_damage=stop_at_damage,
            refuse_empty=refuse_empty,
        )
        for record in records:
            if type(record) is tuple:
                topic = channels.get(record[0])
                if topic is not None:
                    counts[topic] = counts.get(topic, 0) + 1
            elif isinstance(record, Channel):
                channels[record.id] = record.topic
    return dict(sorted(counts.items()))


# --- decoding ----------------------------------------------------------------------------------
def _decode(
    record: MessageRow,
    channels: dict[int, Channel],
    wanted: frozenset[str] | None,
    stats: ReadStats,
    name: str,
    raw: frozenset[str] = frozenset(),
) -> RecordedMessage | RecordedRaw | None:
    channel_id, log_time, data = record
    channel = channels.get(channel_id)
    if channel is None:
        stats.unknown_channel += 1
        _warn(stats, "%s: message on unknown channel %d skipped", name, channel_id)
        return None
    if wanted is not None and channel.topic not in wanted:
        return None
    if channel.message_encoding != "json":
        stats.not_json += 1
        encoding = channel.message_encoding
        _warn(stats, "%s: %s uses encoding %r, not json; skipped", name, channel.topic, encoding)
        return None
    if channel.topic in raw:
        stats.messages += 1
        return _entry(RecordedRaw, _RAW_SLOTS, channel.topic, log_time, data)
    try:
        message = loads_json(data)
    except ValueError as err:  # loads_json raises nothing else (UnicodeDecodeError is one)
        message = err
    if not isinstance(message, dict):
        stats.malformed += 1
        _warn(
            stats,
            "%s: %s message at %d ns is not a JSON object (%s); skipped",
            name,
            channel.topic,
            log_time,
            message if isinstance(message, Exception) else type(message).__name__,
        )
        return None
    stats.messages += 1
    return _entry(RecordedMessage, _MESSAGE_SLOTS, channel.topic, log_time, message)


def decode_json_object(data: bytes) -> dict[str, Any] | None:
    """A ``RecordedRaw`` payload decoded as ``read_entries`` decodes messages; None when it is not a JSON
    object (which ``read_entries`` would have skipped and counted as malformed)."""
    try:
        message = loads_json(data)
    except ValueError:
        return None
    return message if isinstance(message, dict) else None


def _warn(stats: ReadStats, fmt: str, *args: object) -> None:
    if stats.skipped <= _MAX_WARNINGS:
        logger.warning(fmt, *args)


# --- framing -----------------------------------------------------------------------------------
def _open(source: Source, stack: ExitStack) -> tuple[BinaryIO, str]:
    if isinstance(source, str | Path):
        try:
            # closed by the caller's ExitStack when the reading generator finishes or is dropped
            stream: BinaryIO = stack.enter_context(Path(source).open("rb"))  # noqa: SIM115
        except OSError as err:
            raise LogReadError(f"cannot open recording {source}: {err}") from err
        return stream, str(source)
    return source, str(getattr(source, "name", "<stream>"))


def _read_up_to(stream: BinaryIO, size: int, name: str) -> bytes:
    """Up to ``size`` bytes; fewer only at the end of the stream."""
    pieces: list[bytes] = []
    remaining = size
    try:
        if size <= _READ_PIECE:
            # The usual case (every record head, most bodies): one read returns it all, or the end.
            piece = stream.read(size)
            if len(piece) == size or not piece:
                return piece
            pieces.append(piece)
            remaining -= len(piece)
        while remaining > 0:
            piece = stream.read(min(remaining, _READ_PIECE))
            if not piece:
                break
            pieces.append(piece)
            remaining -= len(piece)
    except OSError as err:
        raise LogReadError(f"cannot read recording {name}: {err}") from err
    return b"".join(pieces)


def _records(
    stream: BinaryIO,
    name: str,
    stats: ReadStats,
    *,
    decode_chunks: bool,
    chunk_headers: bool = False,
    skip_channels: Collection[int] = frozenset(),
    stop_at_damage: bool = False,
    refuse_empty: bool = False,
    warn_cut: bool = True,
) -> Iterator[RawRecord]:
    """Records of the data section (messages as ``MessageRow``), chunks opened up; stops at DataEnd or,
    with a warning, at a cut (and with ``stop_at_damage`` at damage). Without ``decode_chunks`` a chunk is
    left out, or with ``chunk_headers`` given as the ``Chunk`` record itself, not decompressed (its
    messages' time span).

    Messages inside chunks on ``skip_channels`` (which the caller may grow while reading) are left out."""
    magic = _read_up_to(stream, len(MCAP_MAGIC), name)
    if not magic_complete(magic, name, refuse_empty=refuse_empty):
        _cut(stats, name, len(magic), "inside the file magic", warn_cut)
        return
    offset = len(MCAP_MAGIC)
    while True:
        head = _read_up_to(stream, _FRAME_HEAD.size, name)
        if len(head) < _FRAME_HEAD.size:
            where = "inside a record header" if head else "before the data section ended"
            _cut(stats, name, offset, where, warn_cut)
            return
        opcode, length = _FRAME_HEAD.unpack(head)
        try:
            if length > MAX_RECORD_BYTES:
                raise RecordingDamaged(name, oversized_record(offset, opcode, length))
            body = _read_up_to(stream, length, name)
            if len(body) < length:
                where = f"inside a record: {len(body)} of its {length} bytes present"
                _cut(stats, name, offset, where, warn_cut)
                return
            if opcode == Opcode.DATA_END:
                stats.complete = True
                return  # the summary section repeats what we have already read
            records: list[RawRecord] = []
            if opcode != Opcode.CHUNK or decode_chunks or chunk_headers:
                records = _parse(opcode, body, name, offset, skip_channels, open_chunks=decode_chunks)
        except RecordingDamaged as err:
            if not stop_at_damage:
                raise
            stats.stop = err.stop
            logger.warning("%s is %s; read everything before it", name, err.stop.describe())
            return
        yield from records
        offset += _FRAME_HEAD.size + length


def _cut(stats: ReadStats, name: str, offset: int, reason: str, warn: bool) -> None:
    stats.truncated = True
    stats.stop = ReadStop(CUT, offset, reason)
    if warn:
        logger.warning("%s is %s; read everything before the cut", name, stats.stop.describe())


_PLAIN_RECORDS: dict[int, Any] = {
    Opcode.CHANNEL: Channel,
    Opcode.METADATA: Metadata,
    Opcode.ATTACHMENT: Attachment,
}


def _parse(
    opcode: int,
    body: bytes,
    name: str,
    offset: int,
    skip_channels: Collection[int] = frozenset(),
    *,
    open_chunks: bool = True,
) -> list[RawRecord]:
    """The records one complete frame holds: none (skipped kinds), one, or a chunk's contents (without
    ``open_chunks``: the chunk record itself)."""
    if opcode not in (Opcode.MESSAGE, Opcode.CHUNK) and opcode not in _PLAIN_RECORDS:
        return []  # header, schema, indexes: nothing we need
    try:
        data = ReadDataStream(BytesIO(body))
        if opcode == Opcode.MESSAGE:
            message = Message.read(data, len(body))
            return [(message.channel_id, message.log_time, message.data)]
        if opcode == Opcode.CHUNK:
            chunk = Chunk.read(data)
            return _chunk_records(chunk, name, offset, skip_channels) if open_chunks else [chunk]
        return [_PLAIN_RECORDS[opcode].read(data)]
    except LogReadError:
        raise
    except (McapError, struct.error, UnicodeDecodeError, ValueError) as err:
        raise RecordingDamaged(name, ReadStop(DAMAGED, offset, f"opcode {opcode:#x}: {err}")) from err


def _chunk_records(chunk: Chunk, name: str, offset: int, skip_channels: Collection[int]) -> list[RawRecord]:
    try:
        data = decompress(chunk)
    except UnsupportedCompression as err:
        raise LogReadError(f"{name}: chunk at byte {offset}: {err}") from err
    # fastcrc's CRC-32 (ISO-HDLC: zlib's, the one MCAP uses) runs ~7x zlib's here: zlib's took a tenth
    # of the metrics pass every trial ends with (~17 MB of chunks).
    if chunk.uncompressed_crc != 0 and crc32.iso_hdlc(data) != chunk.uncompressed_crc:
        raise RecordingDamaged(name, ReadStop(DAMAGED, offset, "the chunk fails its CRC check"))
    rows, status, _ = chunk_layout(data, skip_mask(skip_channels))
    if status == LAYOUT_CUT_HEAD:
        raise RecordingDamaged(name, ReadStop(DAMAGED, offset, "the chunk ends inside a record header"))
    if status == LAYOUT_CUT_BODY:
        raise RecordingDamaged(name, ReadStop(DAMAGED, offset, "the chunk ends inside a record"))
    records: list[RawRecord] = []
    head_size = _MESSAGE_HEAD.size
    message_key = _MESSAGE_KEY.unpack_from
    message_opcode = int(Opcode.MESSAGE)  # a plain int: compared once per record
    # The kernel left out the messages on skip_channels; what is left is built here, in file order.
    for start, end, opcode in rows.tolist():
        if opcode == message_opcode and end - start >= head_size:
            # The hot path of every analysis: unpack in place instead of a stream object per message.
            channel_id, log_time = message_key(data, start)
            records.append((channel_id, log_time, data[start + head_size : end]))
        elif opcode in (Opcode.MESSAGE, Opcode.CHANNEL):
            records.extend(_parse(opcode, data[start:end], name, offset))
    return records
