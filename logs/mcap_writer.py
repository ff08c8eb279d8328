"""A chunked MCAP writer whose per-message cost is one ``struct.pack`` and two buffer appends.

The mcap library's ``Writer`` builds a ``Message`` dataclass per message and writes it through a
``RecordBuilder`` (five ``struct.pack`` calls and two seeks in a ``BytesIO``), ~4 us a message, measured;
the lockstep trial records ~1300 messages per simulated second. ``ChunkedMcapWriter`` keeps the open chunk
in a ``bytearray``, packs each message record's fixed fields with one precomputed ``struct``, and keeps each
channel's message index as a flat list: ~1 us a message.

Everything else (header, schemas, channels, attachments, metadata, the summary section and the footer) is
rare and written with the mcap library's own record classes, in the same order and layout as its
``Writer``: given the same calls, both produce the same bytes (a test compares them, uncompressed and
with zstd at the library's level 3). Chunk compression is ``zstd`` (level ``ZSTD_LEVEL`` unless told),
``lz4`` (needs the ``lz4`` package), or none.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable, Mapping, Sequence
from typing import BinaryIO

import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

MAGIC = b"\x89MCAP0\r\n"
# zstd level 1 on the lockstep trial's chunks: ~40 % less time than the library's default level 3, and
# (for this JSON) no bigger. Measured on the default scenario's 77 chunks: 65 ms vs 104 ms.
ZSTD_LEVEL = 1
# opcode, record length, channel id, sequence, log time, publish time
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")
_MESSAGE_FIXED = _MESSAGE_HEAD.size - 9  # record length = fixed fields + data
_MESSAGE_INDEX_HEAD = struct.Struct("<BQHI")  # opcode, record length, channel id, entries' byte length


def _compressor(compression: str, zstd_level: int) -> Callable[[bytes], bytes] | None:
    if compression == "zstd":
        return zstandard.ZstdCompressor(level=zstd_level).compress
    if compression == "lz4":
        import lz4.frame  # type: ignore[import-untyped]  # optional: only when asked for

        compress: Callable[[bytes], bytes] = lz4.frame.compress
        return compress
    if compression == "":
        return None
    raise ValueError(f"unknown MCAP chunk compression {compression!r}; use 'zstd', 'lz4' or ''")


class ChunkedMcapWriter:
    """Writes an MCAP file to ``stream``: chunked, every index, statistics and summary offsets.

    ``compression`` is ``"zstd"``, ``"lz4"`` or ``""``. A chunk closes when its uncompressed records exceed
    ``chunk_size`` bytes, on ``flush()`` and on ``finish()``; a chunk without messages is never written.
    ``finish()`` writes the summary and footer but does not close ``stream``.
    """

    def __init__(
        self, stream: BinaryIO, *, chunk_size: int, compression: str = "zstd", zstd_level: int = ZSTD_LEVEL
    ) -> None:
        self._stream = stream
        self._chunk_size = chunk_size
        self._compression = compression
        self._compress = _compressor(compression, zstd_level)
        self._records = RecordBuilder()  # records outside chunks, written at the next _write_records
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._chunk_indexes: list[ChunkIndex] = []
        self._attachment_indexes: list[AttachmentIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._channel_message_counts: dict[int, int] = {}
        self._message_count = 0
        self._message_start = 0
        self._message_end = 0
        self._attachment_count = 0
        self._metadata_count = 0
        # The open chunk: its records, per channel [log time, offset, log time, offset, ...], times.
        self._chunk = bytearray()
        self._chunk_index: dict[int, list[int]] = {}
        self._chunk_messages = 0
        self._chunk_start = 0
        self._chunk_end = 0

    # --- records outside the hot path ----------------------------------------------------------
    def start(self, profile: str = "", library: str = "") -> None:
        self._stream.write(MAGIC)
        Header(profile, library).write(self._records)
        self._write_records()

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        schema = Schema(id=len(self._schemas) + 1, data=data, encoding=encoding, name=name)
        self._schemas.append(schema)
        self._into_chunk(schema)
        return schema.id

    def register_channel(
        self, topic: str, message_encoding: str, schema_id: int, metadata: Mapping[str, str] | None = None
    ) -> int:
        channel = Channel(
            id=len(self._channels) + 1,
            topic=topic,
            message_encoding=message_encoding,
            schema_id=schema_id,
            metadata=dict(metadata or {}),
        )
        self._channels.append(channel)
        self._into_chunk(channel)
        return channel.id

    def _into_chunk(self, record: Schema | Channel) -> None:
        # Schemas and channels travel in the chunk that first needs them, as the library's writer does.
        builder = RecordBuilder()
        record.write(builder)
        self._chunk += builder.end()
        if len(self._chunk) > self._chunk_size:
            self._finish_chunk()

    def add_attachment(
        self, create_time: int, log_time: int, name: str, media_type: str, data: bytes
    ) -> None:
        self._write_records()
        offset = self._stream.tell()
        self._attachment_count += 1
        Attachment(
            create_time=create_time, log_time=log_time, name=name, media_type=media_type, data=data
        ).write(self._records)
        self._attachment_indexes.append(
            AttachmentIndex(
                offset=offset,
                length=self._records.count,
                create_time=create_time,
                log_time=log_time,
                data_size=len(data),
                name=name,
                media_type=media_type,
            )
        )
        self._write_records()

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        self._write_records()
        offset = self._stream.tell()
        self._metadata_count += 1
        Metadata(name=name, metadata=dict(data)).write(self._records)
        self._metadata_indexes.append(MetadataIndex(offset=offset, length=self._records.count, name=name))
        self._write_records()

    # --- the hot path --------------------------------------------------------------------------
    def add_message(
        self, channel_id: int, log_time: int, data: bytes, publish_time: int, sequence: int
    ) -> None:
        chunk = self._chunk
        entries = self._chunk_index.get(channel_id)
        if entries is None:
            entries = self._chunk_index[channel_id] = []
        entries.append(log_time)
        entries.append(len(chunk))
        chunk += _MESSAGE_HEAD.pack(
            Opcode.MESSAGE, _MESSAGE_FIXED + len(data), channel_id, sequence, log_time, publish_time
        )
        chunk += data
        if self._chunk_messages == 0 or log_time < self._chunk_start:
            self._chunk_start = log_time
        if log_time > self._chunk_end:
            self._chunk_end = log_time
        self._chunk_messages += 1
        if self._message_count == 0 or log_time < self._message_start:
            self._message_start = log_time
        if log_time > self._message_end:
            self._message_end = log_time
        self._message_count += 1
        counts = self._channel_message_counts
        counts[channel_id] = counts.get(channel_id, 0) + 1
        if len(chunk) > self._chunk_size:
            self._finish_chunk()

    # --- chunks --------------------------------------------------------------------------------
    def _finish_chunk(self) -> None:
        if self._chunk_messages == 0:
            return
        records = bytes(self._chunk)
        compressed = records if self._compress is None else self._compress(records)
        chunk = Chunk(
            compression=self._compression,
            data=compressed,
            message_start_time=self._chunk_start,
            message_end_time=self._chunk_end,
            uncompressed_crc=zlib.crc32(records),
            uncompressed_size=len(records),
        )
        self._write_records()
        chunk_start = self._stream.tell()
        chunk.write(self._records)
        chunk_length = self._records.count
        self._write_records()
        index_start = self._stream.tell()
        offsets: dict[int, int] = {}
        index_bytes = bytearray()
        for channel_id, entries in self._chunk_index.items():
            offsets[channel_id] = index_start + len(index_bytes)
            size = 8 * len(entries)
            index_bytes += _MESSAGE_INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, 6 + size, channel_id, size)
            index_bytes += struct.pack(f"<{len(entries)}Q", *entries)
        self._stream.write(index_bytes)
        self._chunk_indexes.append(
            ChunkIndex(
                message_start_time=self._chunk_start,
                message_end_time=self._chunk_end,
                chunk_start_offset=chunk_start,
                chunk_length=chunk_length,
                message_index_offsets=offsets,
                message_index_length=len(index_bytes),
                compression=self._compression,
                compressed_size=len(compressed),
                uncompressed_size=len(records),
            )
        )
        self._chunk = bytearray()
        self._chunk_index = {}
        self._chunk_messages = 0
        self._chunk_start = 0
        self._chunk_end = 0

    def _write_records(self) -> None:
        self._stream.write(self._records.end())

    def flush(self) -> None:
        """Close the open chunk (if it holds messages), write it out, flush the stream."""
        self._finish_chunk()
        self._write_records()
        self._stream.flush()

    # --- the end -------------------------------------------------------------------------------
    def finish(self) -> None:
        """Close the open chunk, then write data end, summary (schemas, channels, statistics, chunk,
        attachment and metadata indexes, summary offsets), footer and the closing magic."""
        self._finish_chunk()
        DataEnd(0).write(self._records)  # no data-section CRC, as the library writes by default
        self._write_records()
        summary_start = self._stream.tell()
        summary = RecordBuilder()
        offsets: list[SummaryOffset] = []
        statistics = Statistics(
            attachment_count=self._attachment_count,
            channel_count=len(self._channels),
            channel_message_counts=self._channel_message_counts,
            chunk_count=len(self._chunk_indexes),
            message_count=self._message_count,
            message_end_time=self._message_end,
            message_start_time=self._message_start,
            metadata_count=self._metadata_count,
            schema_count=len(self._schemas),
        )
        groups: tuple[tuple[Opcode, Sequence[McapRecord]], ...] = (
            (Opcode.SCHEMA, self._schemas),
            (Opcode.CHANNEL, self._channels),
            (Opcode.STATISTICS, [statistics]),
            (Opcode.CHUNK_INDEX, self._chunk_indexes),
            (Opcode.ATTACHMENT_INDEX, self._attachment_indexes),
            (Opcode.METADATA_INDEX, self._metadata_indexes),
        )
        for opcode, records in groups:
            group_start = summary.count
            for record in records:
                record.write(summary)
            offsets.append(
                SummaryOffset(
                    group_opcode=opcode,
                    group_start=summary_start + group_start,
                    group_length=summary.count - group_start,
                )
            )
        summary_offset_start = summary_start + summary.count
        for offset in offsets:
            offset.write(summary)
        summary_data = summary.end()
        footer_summary_start = 0 if not summary_data else summary_start
        crc = zlib.crc32(summary_data)
        crc = zlib.crc32(
            struct.pack("<BQQQ", Opcode.FOOTER, 20, footer_summary_start, summary_offset_start), crc
        )
        self._stream.write(summary_data)
        Footer(
            summary_start=footer_summary_start, summary_offset_start=summary_offset_start, summary_crc=crc
        ).write(self._records)
        self._write_records()
        self._stream.write(MAGIC)
