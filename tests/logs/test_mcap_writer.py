"""Our chunked MCAP writer writes the bytes the mcap library's Writer writes, given the same calls."""

from __future__ import annotations

import io
import random

import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from logs.mcap_writer import ChunkedMcapWriter

_LIBRARY_COMPRESSION = {"": CompressionType.NONE, "zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4}


def _script(seed: int) -> list[tuple[str, tuple[object, ...]]]:
    """A random but valid sequence of writer calls: schemas, channels, messages (times not monotonic),
    metadata, attachments and flushes."""
    rng = random.Random(seed)
    calls: list[tuple[str, tuple[object, ...]]] = [("start", ("profile-x", "lib-y"))]
    schemas = channels = 0
    t = 0
    sequences: dict[int, int] = {}
    for _ in range(rng.randrange(200, 800)):
        roll = rng.random()
        if schemas == 0 or roll < 0.01:
            schemas += 1
            calls.append(
                ("register_schema", (f"s{schemas}", "jsonschema", rng.randbytes(rng.randrange(300))))
            )
        elif channels == 0 or roll < 0.03:
            channels += 1
            metadata = {f"k{i}": f"v{rng.random()}" for i in range(rng.randrange(3))}
            calls.append(
                ("register_channel", (f"topic/{channels}", "json", rng.randint(1, schemas), metadata))
            )
        elif roll < 0.04:
            calls.append(("add_metadata", (f"m{rng.randrange(9)}", {"a": str(rng.random()), "b": ""})))
        elif roll < 0.05:
            data = rng.randbytes(rng.randrange(5000))
            calls.append(
                ("add_attachment", (rng.randrange(10**9), t, f"file{rng.randrange(9)}", "x/y", data))
            )
        elif roll < 0.06:
            calls.append(("flush", ()))
        else:
            channel = rng.randint(1, channels)
            t = max(0, t + rng.randint(-2_000_000, 20_000_000))  # sometimes back in time
            sequence = sequences.get(channel, 0)
            sequences[channel] = sequence + 1
            payload = rng.randbytes(rng.choice([0, 10, 120, 1500, 20_000]))
            calls.append(("add_message", (channel, t, payload, t, sequence)))
    return calls


def _library_bytes(calls: list[tuple[str, tuple[object, ...]]], compression: str, chunk_size: int) -> bytes:
    buffer = io.BytesIO()
    writer = Writer(buffer, chunk_size=chunk_size, compression=_LIBRARY_COMPRESSION[compression])
    for name, args in calls:  # add_message takes (channel, log time, data, publish time, sequence) in both
        getattr(writer, name)(*args)
    writer.finish()
    return buffer.getvalue()


def _our_bytes(
    calls: list[tuple[str, tuple[object, ...]]], compression: str, chunk_size: int, zstd_level: int
) -> bytes:
    buffer = io.BytesIO()
    writer = ChunkedMcapWriter(buffer, chunk_size=chunk_size, compression=compression, zstd_level=zstd_level)
    for name, args in calls:
        getattr(writer, name)(*args)
    writer.finish()
    return buffer.getvalue()


@pytest.mark.parametrize("compression", ["", "zstd", "lz4"])
@pytest.mark.parametrize("seed", range(4))
def test_same_calls_give_the_library_writers_bytes(seed: int, compression: str) -> None:
    calls = _script(seed)
    chunk_size = random.Random(seed).choice([1, 4096, 64 * 1024, 1 << 20])
    theirs = _library_bytes(calls, compression, chunk_size)
    # The library compresses zstd at level 3; lz4 frames are deterministic at the default settings.
    ours = _our_bytes(calls, compression, chunk_size, zstd_level=3)
    assert ours == theirs


def test_default_zstd_level_reads_back_with_the_library_reader() -> None:
    calls = _script(11)
    data = _our_bytes(calls, "zstd", 64 * 1024, zstd_level=1)
    written = [args for name, args in calls if name == "add_message"]
    reader = make_reader(io.BytesIO(data))
    read = [(c.id, m.log_time, m.data, m.sequence) for _, c, m in reader.iter_messages(log_time_order=False)]
    assert read == [(channel, t, payload, sequence) for channel, t, payload, _, sequence in written]
    summary = reader.get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == len(written)


def test_unknown_compression_is_refused() -> None:
    with pytest.raises(ValueError, match="compression"):
        ChunkedMcapWriter(io.BytesIO(), chunk_size=1024, compression="brotli")
