"""Recordings whose chunks another tool compressed with lz4 (rosbag2's MCAP storage, ``mcap convert``):
read, diagnosed and recovered as our own zstd ones; damaged lz4 data and unknown compressions are named."""

from __future__ import annotations

from pathlib import Path

import lz4.frame
import pytest
import zstandard
from mcap.records import Chunk
from mcap.writer import CompressionType

from logs.chunk_codec import MAX_UNCOMPRESSED_BYTES, UnsupportedCompression, decompress
from logs.doctor import diagnose
from logs.errors import LogReadError
from logs.metrics import compute_metrics
from logs.reader import read_messages
from logs.recorder import McapRecorder
from logs.recover import NothingRecoverable, recover
from logs.synthetic import synthetic_metadata, synthetic_trial
from tests.mcap_rewrite import rewrite

DURATION_S = 6


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(our zstd recording of a synthetic trial, the same converted to lz4 chunks)."""
    folder = tmp_path_factory.mktemp("lz4")
    ours = folder / "zstd.mcap"
    with McapRecorder(ours) as recorder:
        recorder.add_metadata("scenario", synthetic_metadata(DURATION_S, "rocky"))
        for topic, t, message in synthetic_trial(DURATION_S, wobble_m=0.3, terrain="rocky"):
            recorder.publish(topic, t, message)
    converted = folder / "lz4.mcap"
    rewrite(ours, converted, compression=CompressionType.LZ4)
    return ours, converted


def test_lz4_chunks_read_as_the_same_messages(recordings: tuple[Path, Path]) -> None:
    ours, converted = recordings
    original = [(m.topic, m.log_time_ns, m.message) for m in read_messages(ours)]
    assert len(original) > 1000
    assert [(m.topic, m.log_time_ns, m.message) for m in read_messages(converted)] == original


def test_doctor_and_metrics_on_lz4_chunks(recordings: tuple[Path, Path]) -> None:
    ours, converted = recordings
    findings = diagnose(converted)
    assert findings.healthy, findings.problems
    assert set(findings.chunk_compression) == {"lz4"} and findings.chunks > 1
    assert findings.messages == diagnose(ours).messages
    assert compute_metrics(converted) == compute_metrics(ours)


def test_a_damaged_lz4_chunk_is_named_and_recover_keeps_the_others(
    recordings: tuple[Path, Path], tmp_path: Path
) -> None:
    data = bytearray(recordings[1].read_bytes())
    frame = data.index(b"\x04\x22\x4d\x18", len(data) // 2)  # an lz4 frame's magic, past the middle
    data[frame + 16 : frame + 80] = bytes(64)
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    with pytest.raises(LogReadError, match="damaged"):
        list(read_messages(damaged))
    findings = diagnose(damaged)
    assert findings.chunks_damaged == 1
    result = recover(damaged, tmp_path / "fixed.mcap")
    assert result.chunks_dropped == 1 and result.chunks_kept == findings.chunks - 1
    assert diagnose(tmp_path / "fixed.mcap").healthy


def _chunk(compression: str, data: bytes, uncompressed_size: int) -> Chunk:
    return Chunk(
        compression=compression,
        data=data,
        message_start_time=0,
        message_end_time=0,
        uncompressed_crc=0,
        uncompressed_size=uncompressed_size,
    )


def test_a_damaged_chunk_size_is_damage_not_a_crash(recordings: tuple[Path, Path], tmp_path: Path) -> None:
    """A chunk whose uncompressed size reads near 2^64 (a damaged header) made the decompressors raise
    OverflowError past the reader's, the doctor's and recover's handlers."""
    for compression, records in (
        ("lz4", lz4.frame.compress(b"x" * 100)),
        ("zstd", zstandard.compress(b"x" * 100)),
    ):
        for size in (2**64 - 1, 2**62, MAX_UNCOMPRESSED_BYTES + 1):
            with pytest.raises(ValueError, match="more than"):
                decompress(_chunk(compression, records, size))
    # The same in a file: the size field of the first chunk (after its opcode, length and two times) set high.
    data = bytearray(recordings[1].read_bytes())
    chunk = 8  # past the magic: walk the records (opcode, u64 length, body) to the first chunk (opcode 6)
    while data[chunk] != 0x06:
        chunk += 9 + int.from_bytes(data[chunk + 1 : chunk + 9], "little")
    size_at = chunk + 9 + 8 + 8  # its body: message start time, message end time, uncompressed size
    data[size_at : size_at + 8] = (2**64 - 1).to_bytes(8, "little")
    damaged = tmp_path / "big.mcap"
    damaged.write_bytes(bytes(data))
    with pytest.raises(LogReadError, match="damaged"):
        list(read_messages(damaged))
    assert diagnose(damaged).chunks_damaged == 1
    # The lost chunk held every channel record (the mcap writer puts them in the chunk of their first
    # message): the messages after it cannot be decoded, so there is nothing to recover, and recover says so.
    with pytest.raises(NothingRecoverable, match=r"channel record was lost \(in the 1 damaged chunk"):
        recover(damaged, tmp_path / "fixed.mcap")
    assert not (tmp_path / "fixed.mcap").exists()


def test_decompress_names_an_unknown_compression_and_a_wrong_size() -> None:
    records = b"\x01" * 100
    assert decompress(_chunk("lz4", lz4.frame.compress(records), 100)) == records
    assert decompress(_chunk("", records, 100)) == records
    with pytest.raises(UnsupportedCompression, match="'brotli'"):
        decompress(_chunk("brotli", records, 100))
    with pytest.raises(ValueError, match="decompressed to 100 bytes, the chunk says 99"):
        decompress(_chunk("lz4", lz4.frame.compress(records), 99))
    # A chunk whose data hold far more than its header says is refused without inflating all of it.
    with pytest.raises(ValueError, match="decompressed to 101 bytes, the chunk says 100"):
        decompress(_chunk("lz4", lz4.frame.compress(b"\x00" * 10_000_000), 100))
    with pytest.raises(ValueError, match="zstd frame holds 10000000 bytes, the chunk says 100"):
        decompress(_chunk("zstd", zstandard.ZstdCompressor().compress(b"\x00" * 10_000_000), 100))
    with pytest.raises(ValueError, match="lz4 data do not decompress"):
        decompress(_chunk("lz4", b"not an lz4 frame", 100))
