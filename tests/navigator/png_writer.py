"""A minimal PNG writer for tests: true greyscale (8/16-bit) and palette images, which imsave cannot write."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def write_png(path: Path, pixels: np.ndarray, *, palette: np.ndarray | None = None) -> None:
    """``pixels`` (rows, cols): uint8 or uint16 grey levels, or uint8 palette indices when ``palette``
    (``(n, 3)`` uint8 colours) is given. Row 0 is the image's top."""
    rows, cols = pixels.shape
    depth = 16 if pixels.dtype == np.uint16 else 8
    colour_type = 3 if palette is not None else 0
    raw = b"".join(b"\x00" + pixels[r].astype(">u2" if depth == 16 else "u1").tobytes() for r in range(rows))
    data = b"\x89PNG\r\n\x1a\n" + _chunk(
        b"IHDR", struct.pack(">IIBBBBB", cols, rows, depth, colour_type, 0, 0, 0)
    )
    if palette is not None:
        data += _chunk(b"PLTE", np.asarray(palette, dtype=np.uint8).tobytes())
    data += _chunk(b"IDAT", zlib.compress(raw)) + _chunk(b"IEND", b"")
    path.write_bytes(data)
