"""A recording damaged partway, for the tools that must keep what comes before the damage."""

from __future__ import annotations

from io import BytesIO

from mcap.opcode import Opcode

from logs.frames import FrameWalk


def damage_a_middle_chunk(recording: bytes) -> tuple[bytes, int]:
    """``recording`` with the last 32 bytes of its middle chunk (compressed data) inverted, and the byte
    offset of that chunk: the records before it read, the chunk itself does not."""
    chunks = [
        frame for frame in FrameWalk(BytesIO(recording), "<test>").frames() if frame.opcode == Opcode.CHUNK
    ]
    assert len(chunks) >= 3, "a recording with a chunk before and after the damaged one"
    chunk = chunks[len(chunks) // 2]
    end = chunk.offset + chunk.size
    damaged = bytearray(recording)
    damaged[end - 32 : end] = bytes(b ^ 0xFF for b in damaged[end - 32 : end])
    return bytes(damaged), chunk.offset
