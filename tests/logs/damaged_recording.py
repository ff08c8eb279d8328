"""Recordings for the log tools' tests: a small synthetic trial, and one damaged partway (the tools must
keep what comes before the damage)."""

from __future__ import annotations

from io import BytesIO
from pathlib import Path

from mcap.opcode import Opcode

from logs.frames import FrameWalk
from logs.recorder import McapRecorder
from logs.synthetic import synthetic_metadata, write_synthetic_trial


def write_small_trial(path: Path, seconds: float = 4.0, *, trial_mode: str | None = None) -> Path:
    """A synthetic trial of ``seconds`` with its scenario metadata, recorded to ``path``; with
    ``trial_mode`` also a ``trial`` record of that mode (``sim-lockstep``: as ``hil.trial`` writes it)."""
    with McapRecorder(path) as recorder:
        recorder.add_metadata("scenario", synthetic_metadata(seconds))
        if trial_mode is not None:
            recorder.add_metadata("trial", {"mode": trial_mode})
        write_synthetic_trial(recorder, seconds)
    return path


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
