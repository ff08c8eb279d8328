"""An MCAP chunk's records, decompressed: the compressions the MCAP specification names (zstd, lz4) and none.

Our recorder writes zstd, but a team also reads recordings made by other tools (rosbag2's MCAP storage, the
Foxglove SDK, `mcap` CLI conversions), and those are often lz4. The reader, ``rover logs doctor`` and
``rover logs recover`` all open chunks here, so each reads what the others read.
"""

from __future__ import annotations

import threading

import lz4.frame
import zstandard
from mcap.records import Chunk

_THREAD_STATE = threading.local()
# The most a chunk may say it holds (as logs.frames bounds a record's length): the size comes from the file,
# and a damaged one near 2^64 made the decompressors raise OverflowError / MemoryError past every handler.
MAX_UNCOMPRESSED_BYTES = 1 << 30


class UnsupportedCompression(ValueError):
    """The chunk uses a compression this stack does not read (a valid file, not a damaged one)."""


def decompress(chunk: Chunk) -> bytes:
    """The chunk's record bytes. ``UnsupportedCompression`` for a compression other than zstd, lz4 or none
    (""); ``ValueError`` naming the problem when the data do not decompress to the chunk's stated size.
    Neither decompression is let past that size (plus a byte, to tell a longer one): a damaged or hostile
    chunk cannot make the reader allocate more than its header admits, and a header
    may not admit more than ``MAX_UNCOMPRESSED_BYTES``."""
    compression = chunk.compression
    if not 0 <= chunk.uncompressed_size <= MAX_UNCOMPRESSED_BYTES:
        raise ValueError(
            f"the chunk says it holds {chunk.uncompressed_size} bytes, more than {MAX_UNCOMPRESSED_BYTES} "
            "(a damaged size)"
        )
    if compression == "zstd":
        try:
            # A frame that states its size is decompressed to that size whatever the limit: check it first.
            stated = zstandard.frame_content_size(chunk.data)
            if stated >= 0 and stated != chunk.uncompressed_size:
                raise ValueError(f"zstd frame holds {stated} bytes, the chunk says {chunk.uncompressed_size}")
            data = _zstd().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
        except zstandard.ZstdError as err:
            raise ValueError(f"zstd data do not decompress: {err}") from err
    elif compression == "lz4":
        try:
            data = lz4.frame.LZ4FrameDecompressor().decompress(
                chunk.data, max_length=chunk.uncompressed_size + 1
            )
        except RuntimeError as err:  # what lz4.frame raises on a damaged or cut frame
            raise ValueError(f"lz4 data do not decompress: {err}") from err
    elif compression == "":
        data = chunk.data
    else:
        raise UnsupportedCompression(
            f"compression {compression!r} is not one this stack reads (zstd, lz4 or none)"
        )
    if len(data) != chunk.uncompressed_size:
        raise ValueError(f"decompressed to {len(data)} bytes, the chunk says {chunk.uncompressed_size}")
    return data


def _zstd() -> zstandard.ZstdDecompressor:
    """This thread's zstd decompressor, made once and reused for every chunk: a new one per chunk cost
    ~8 % of the decompression (a trial's ~84 chunks). One per thread, as zstandard requires."""
    decompressor: zstandard.ZstdDecompressor | None = getattr(_THREAD_STATE, "zstd", None)
    if decompressor is None:
        decompressor = _THREAD_STATE.zstd = zstandard.ZstdDecompressor()
    return decompressor
