"""Where a decompressed MCAP chunk's records are, found in one compiled pass.

A chunk of a lockstep trial holds ~650 records, most of them messages on channels an analysis does not
want (the metrics read 6 of 18 topics; ``can/frames`` alone is more than half of every chunk). Walking the
records in Python (two ``struct`` unpacks each) was a third of the metrics pass every trial ends with;
this kernel walks them in compiled code and hands back only the records to build.

``chunk_layout(data, skip)`` returns one row ``(start, end, opcode)`` per record kept (``start``: its body,
after the 9-byte opcode + length head) and a status: ``LAYOUT_OK``, or where the chunk is broken
(``LAYOUT_CUT_HEAD``: it ends inside a record head; ``LAYOUT_CUT_BODY``: inside a record). A message
record (opcode 0x05) of at least the 22-byte message head whose channel id ``skip`` marks is left out;
every other record is kept, a short message too, so the caller's parser names what is wrong with it.
``tests/logs/test_chunk_kernel.py`` checks it against a plain Python walk.
"""

from __future__ import annotations

from collections.abc import Collection

import numba
import numpy as np
from numpy.typing import NDArray

LAYOUT_OK = 0
LAYOUT_CUT_HEAD = 1
LAYOUT_CUT_BODY = 2
_MESSAGE_OPCODE = 0x05
_FRAME_HEAD_BYTES = 9  # opcode uint8 + length uint64, little-endian
_MESSAGE_HEAD_BYTES = 22  # channel id uint16, sequence uint32, log time uint64, publish time uint64


@numba.njit(cache=True)
def _little_endian(data: NDArray[np.uint8], start: int, size: int) -> int:
    value = 0
    for index in range(size - 1, -1, -1):
        value = (value << 8) | int(data[start + index])
    return value


@numba.njit(cache=True)
def _kernel(
    data: NDArray[np.uint8], skip: NDArray[np.bool_], rows: NDArray[np.int64]
) -> tuple[int, int, int]:
    """Fills ``rows``; (rows filled, status, offset of the broken record or the end)."""
    size = data.shape[0]
    position = 0
    kept = 0
    while position < size:
        if position + _FRAME_HEAD_BYTES > size:
            return kept, LAYOUT_CUT_HEAD, position
        opcode = int(data[position])
        start = position + _FRAME_HEAD_BYTES
        # A length past what is left, the top byte included, is a cut: compare before adding, so a huge
        # (corrupt) uint64 cannot wrap around.
        if data[position + 8] != 0 or _little_endian(data, position + 1, 8) > size - start:
            return kept, LAYOUT_CUT_BODY, position
        end = start + _little_endian(data, position + 1, 8)
        skipped = False
        if opcode == _MESSAGE_OPCODE and end - start >= _MESSAGE_HEAD_BYTES:
            channel = _little_endian(data, start, 2)
            skipped = channel < skip.shape[0] and skip[channel]
        if not skipped:
            rows[kept, 0] = start
            rows[kept, 1] = end
            rows[kept, 2] = opcode
            kept += 1
        position = end
    return kept, LAYOUT_OK, position


def chunk_layout(data: bytes, skip: NDArray[np.bool_]) -> tuple[NDArray[np.int64], int, int]:
    """(rows of (start, end, opcode) for the records kept, status, offset where the walk stopped)."""
    view = np.frombuffer(data, dtype=np.uint8)
    # Every record takes at least its 9-byte head, so this many rows always suffice.
    rows = np.empty((len(data) // _FRAME_HEAD_BYTES + 1, 3), dtype=np.int64)
    kept, status, offset = _kernel(view, skip, rows)
    return rows[:kept], status, offset


def skip_mask(channels: Collection[int]) -> NDArray[np.bool_]:
    """``skip`` for ``chunk_layout``: True at each channel id in ``channels`` (ids are uint16)."""
    ids = [channel for channel in channels if 0 <= channel < 1 << 16]
    mask = np.zeros(max(ids) + 1 if ids else 0, dtype=np.bool_)
    mask[ids] = True
    return mask
