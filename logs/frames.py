"""The MCAP file as a sequence of framed records (opcode + length + body), for tools that check or repair.

``logs.reader`` decodes messages for analysis; this module stays one level lower so ``doctor`` can check
every record (CRCs, summary, footer) and ``recover`` can copy records byte for byte. It never seeks, and a
record whose bytes end early is reported as the cut (``FrameWalk.cut_at``), not raised.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from io import BytesIO
from typing import BinaryIO

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Chunk

from logs.chunk_codec import decompress
from logs.errors import LogReadError, NotARecording, RecordingDamaged
from logs.read_stop import CUT, DAMAGED, ReadStop

MCAP_MAGIC = b"\x89MCAP0\r\n"
FRAME_HEAD = struct.Struct("<BQ")  # opcode uint8, record length uint64
MAX_RECORD_BYTES = 1 << 30  # a damaged length must not make us allocate terabytes
_READ_PIECE = 1 << 20


def magic_complete(magic: bytes, name: str, *, refuse_empty: bool) -> bool:
    """Whether ``magic`` (the file's first bytes, up to the magic's length) is the MCAP magic. A file that
    ends inside it is a cut before anything was recorded (False), or with ``refuse_empty`` a
    ``NotARecording``, as is a file starting with other bytes."""
    if magic == MCAP_MAGIC:
        return True
    if not MCAP_MAGIC.startswith(magic):
        raise NotARecording(f"{name} is not an MCAP file (it starts with {magic!r}); pass an .mcap recording")
    if refuse_empty:
        what = "is empty (0 bytes)" if not magic else f"holds only {len(magic)} bytes, part of the MCAP magic"
        raise NotARecording(f"{name} {what}: no recording in it (the recorder stopped before writing one?)")
    return False


def oversized_record(offset: int, opcode: int, length: int) -> ReadStop:
    """A record claiming more than ``MAX_RECORD_BYTES``: a damaged length field, not a record of ours."""
    return ReadStop(DAMAGED, offset, f"opcode {opcode:#x}: the record claims {length} bytes")


@dataclass(frozen=True)
class Frame:
    offset: int  # byte offset of the opcode in the file
    opcode: int
    body: bytes

    @property
    def size(self) -> int:
        return FRAME_HEAD.size + len(self.body)


@dataclass
class FrameWalk:
    """Iterate ``frames()``; afterwards ``cut_at`` (byte offset of a cut, or None) and ``end`` are set.

    ``refuse_empty``: a file that ends before its magic is complete is a ``NotARecording``, not a cut."""

    stream: BinaryIO
    name: str
    refuse_empty: bool = False
    cut_at: int | None = None
    cut_reason: str = ""
    end: int = 0  # offset just after the last complete frame (or magic)
    trailing_magic: bool = False

    def frames(self) -> Iterator[Frame]:
        magic = self._read(len(MCAP_MAGIC))
        if not magic_complete(magic, self.name, refuse_empty=self.refuse_empty):
            self._cut(len(magic), "inside the file magic")
            return
        offset = self.end = len(MCAP_MAGIC)
        while True:
            head = self._read(FRAME_HEAD.size)
            if not head:
                self._cut(offset, "before the data section ended")
                return
            if len(head) == len(MCAP_MAGIC) and head == MCAP_MAGIC:
                self.trailing_magic = True
                self.end = offset + len(head)
                return
            if len(head) < FRAME_HEAD.size:
                self._cut(offset, "inside a record header")
                return
            opcode, length = FRAME_HEAD.unpack(head)
            if length > MAX_RECORD_BYTES:
                raise RecordingDamaged(self.name, oversized_record(offset, opcode, length))
            body = self._read(length)
            if len(body) < length:
                self._cut(offset, f"inside a record: {len(body)} of its {length} bytes present")
                return
            yield Frame(offset, opcode, body)
            offset += FRAME_HEAD.size + length
            self.end = offset

    @property
    def stop(self) -> ReadStop | None:
        """The cut as ``logs.read_stop`` words it (None: the walk reached the end, or has not yet)."""
        return None if self.cut_at is None else ReadStop(CUT, self.cut_at, self.cut_reason)

    def _cut(self, offset: int, reason: str) -> None:
        self.cut_at = offset
        self.cut_reason = reason

    def _read(self, size: int) -> bytes:
        pieces: list[bytes] = []
        remaining = size
        try:
            while remaining > 0:
                piece = self.stream.read(min(remaining, _READ_PIECE))
                if not piece:
                    break
                pieces.append(piece)
                remaining -= len(piece)
        except OSError as err:
            raise LogReadError(f"cannot read recording {self.name}: {err}") from err
        return b"".join(pieces)


def chunk_of(frame: Frame) -> Chunk:
    return Chunk.read(ReadDataStream(BytesIO(frame.body)))


def chunk_payload(chunk: Chunk) -> bytes:
    """The chunk's records, decompressed; ``ValueError`` naming the problem (compression, size, CRC)."""
    data = decompress(chunk)
    if chunk.uncompressed_crc != 0 and zlib.crc32(data) != chunk.uncompressed_crc:
        raise ValueError("CRC mismatch")
    return data


def inner_frames(data: bytes) -> Iterator[tuple[int, bytes]]:
    """(opcode, body) of each record inside a decompressed chunk; ``ValueError`` if one is cut."""
    position = 0
    while position < len(data):
        if position + FRAME_HEAD.size > len(data):
            raise ValueError("chunk ends inside a record header")
        opcode, length = FRAME_HEAD.unpack_from(data, position)
        start = position + FRAME_HEAD.size
        end = start + length
        if end > len(data):
            raise ValueError("chunk ends inside a record")
        yield opcode, data[start:end]
        position = end


def attachment_crc_ok(body: bytes) -> bool:
    """An attachment's own CRC (over its body without the CRC field); 0 means "not computed"."""
    if len(body) < 4:
        return False
    (stored,) = struct.unpack_from("<I", body, len(body) - 4)
    return stored == 0 or zlib.crc32(body[:-4]) == stored


OPCODE_NAMES = {int(op): op.name.lower() for op in Opcode}
