"""``rover logs doctor``: check one MCAP recording's structure and integrity and summarise what it holds.

Checks: the magic at both ends; every record framed completely (else: where the file is cut); every
chunk decompresses to its stated size and matches its CRC; every attachment matches its CRC; the data
section CRC in DataEnd; the Statistics record (if any) agrees with what was counted; the file holds a
message (metadata and attachments alone are no recording of a run: a trial writes them before its first
chunk, so a file cut before that chunk's end holds nothing else). Counts per topic with first / last log
time, metadata and attachment names. Problems are listed, never raised, except for
a file that is missing or holds no recording at all (``LogReadError``; ``NotARecording`` for an empty file,
one that ends inside the MCAP magic, or one that is not MCAP), as ``rover can export`` and ``rover logs
csv`` refuse them. A cut and damage are worded as those tools word them (``logs.read_stop``).
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import asdict, dataclass, field
from io import BytesIO
from pathlib import Path
from typing import Any

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Header, Message, Metadata, Statistics

from logs.errors import LogReadError
from logs.frames import (
    FRAME_HEAD,
    MCAP_MAGIC,
    Frame,
    FrameWalk,
    attachment_crc_ok,
    chunk_of,
    chunk_payload,
    inner_frames,
)
from logs.read_stop import DAMAGED, ReadStop


@dataclass
class TopicSummary:
    messages: int = 0
    first_ns: int | None = None
    last_ns: int | None = None
    encoding: str = ""


@dataclass
class DoctorReport:
    path: str
    size_bytes: int = 0
    profile: str = ""
    library: str = ""
    complete: bool = False  # DataEnd reached
    summary_present: bool = False
    footer_present: bool = False
    cut_at: int | None = None
    bytes_after_last_record: int = 0
    chunks: int = 0
    chunks_damaged: int = 0
    chunk_compression: dict[str, int] = field(default_factory=dict)
    data_crc_ok: bool | None = None  # None: no DataEnd, or its CRC was not computed
    messages: int = 0
    topics: dict[str, TopicSummary] = field(default_factory=dict)
    metadata: list[str] = field(default_factory=list)
    attachments: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)

    @property
    def healthy(self) -> bool:
        return not self.problems

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["healthy"] = self.healthy
        return out


def diagnose(path: str | Path) -> DoctorReport:
    source = Path(path)
    try:
        size = source.stat().st_size
        stream = source.open("rb")
    except OSError as err:
        raise LogReadError(f"cannot open recording {source}: {err}") from err
    report = DoctorReport(str(source), size_bytes=size)
    with stream:
        walk = FrameWalk(stream, str(source), refuse_empty=True)
        _Checker(report).run(walk)
    if walk.stop is not None:
        report.cut_at = walk.stop.offset
        report.bytes_after_last_record = size - walk.end
        # recover keeps messages; before the first chunk's end there is none to keep, and it says so
        advice = (
            "`rover logs recover` keeps every complete chunk"
            if report.messages
            else "no complete chunk before it: no message to recover"
        )
        report.problems.append(f"file ({size} bytes) is {walk.stop.describe()}; {advice}")
    elif report.complete and not walk.trailing_magic:
        report.problems.append("the closing magic bytes are missing")
    if not report.messages and walk.stop is None:
        # Metadata and attachments alone are not a recording of a run (a trial writes them before its
        # first chunk closes): never "healthy".
        report.problems.append(_no_messages(report))
    return report


def _no_messages(report: DoctorReport) -> str:
    held = len(report.metadata) + len(report.attachments)
    besides = (
        f", only {len(report.metadata)} metadata and {len(report.attachments)} attachment(s)" if held else ""
    )
    return f"no messages: the recording holds none{besides}"


class _Checker:
    def __init__(self, report: DoctorReport) -> None:
        self.report = report
        self.channels: dict[int, Channel] = {}
        self.crc = zlib.crc32(MCAP_MAGIC)
        self.in_summary = False

    def run(self, walk: FrameWalk) -> None:
        for frame in walk.frames():
            try:
                self._frame(frame)
            except (ValueError, struct.error, UnicodeDecodeError) as err:
                damage = ReadStop(DAMAGED, frame.offset, f"opcode {frame.opcode:#x}: {err}")
                self.report.problems.append(f"record {damage.describe()}")

    def _frame(self, frame: Frame) -> None:
        report = self.report
        if frame.opcode == Opcode.DATA_END:
            report.complete = True
            self.in_summary = True
            (stored,) = struct.unpack_from("<I", frame.body, 0)
            report.data_crc_ok = None if stored == 0 else stored == self.crc
            if report.data_crc_ok is False:
                report.problems.append("data section CRC does not match")
            return
        if not self.in_summary:
            self.crc = zlib.crc32(FRAME_HEAD.pack(frame.opcode, len(frame.body)), self.crc)
            self.crc = zlib.crc32(frame.body, self.crc)
        data = ReadDataStream(BytesIO(frame.body))
        if frame.opcode == Opcode.HEADER:
            header = Header.read(data)
            report.profile, report.library = header.profile, header.library
        elif frame.opcode == Opcode.FOOTER:
            report.footer_present = True
        elif frame.opcode == Opcode.STATISTICS:
            report.summary_present = True
            self._statistics(Statistics.read(data))
        elif self.in_summary:
            report.summary_present = True
        elif frame.opcode == Opcode.CHUNK:
            self._chunk(frame)
        elif frame.opcode == Opcode.CHANNEL:
            self._channel(Channel.read(data))
        elif frame.opcode == Opcode.MESSAGE:
            self._message(Message.read(data, len(frame.body)))
        elif frame.opcode == Opcode.METADATA:
            report.metadata.append(Metadata.read(data).name)
        elif frame.opcode == Opcode.ATTACHMENT:
            name = _attachment_name(frame.body)
            report.attachments.append(name)
            if not attachment_crc_ok(frame.body):
                report.problems.append(f"attachment {name!r} at byte {frame.offset} fails its CRC check")

    def _chunk(self, frame: Frame) -> None:
        report = self.report
        report.chunks += 1
        chunk = chunk_of(frame)
        label = chunk.compression or "none"
        report.chunk_compression[label] = report.chunk_compression.get(label, 0) + 1
        try:
            payload = chunk_payload(chunk)
            records = list(inner_frames(payload))
        except ValueError as err:
            report.chunks_damaged += 1
            report.problems.append(f"chunk {ReadStop(DAMAGED, frame.offset, str(err)).describe()}")
            return
        for opcode, body in records:
            if opcode == Opcode.CHANNEL:
                self._channel(Channel.read(ReadDataStream(BytesIO(body))))
            elif opcode == Opcode.MESSAGE:
                self._message(Message.read(ReadDataStream(BytesIO(body)), len(body)))

    def _channel(self, channel: Channel) -> None:
        self.channels[channel.id] = channel
        summary = self.report.topics.setdefault(channel.topic, TopicSummary())
        summary.encoding = channel.message_encoding

    def _message(self, message: Message) -> None:
        report = self.report
        report.messages += 1
        channel = self.channels.get(message.channel_id)
        topic = channel.topic if channel is not None else f"<unknown channel {message.channel_id}>"
        summary = report.topics.setdefault(topic, TopicSummary())
        summary.messages += 1
        t = message.log_time
        summary.first_ns = t if summary.first_ns is None else min(summary.first_ns, t)
        summary.last_ns = t if summary.last_ns is None else max(summary.last_ns, t)

    def _statistics(self, statistics: Statistics) -> None:
        report = self.report
        if statistics.message_count != report.messages:
            report.problems.append(
                f"summary says {statistics.message_count} messages, the data section holds {report.messages}"
            )
        if statistics.chunk_count != report.chunks:
            report.problems.append(f"summary says {statistics.chunk_count} chunks, found {report.chunks}")


def _attachment_name(body: bytes) -> str:
    data = ReadDataStream(BytesIO(body))
    data.read8()  # log time
    data.read8()  # create time
    return str(data.read_prefixed_string())
