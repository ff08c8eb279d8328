"""``logs.chunk_kernel``: the compiled walk over a chunk's records against a plain Python walk."""

from __future__ import annotations

import struct

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from logs.chunk_kernel import LAYOUT_CUT_BODY, LAYOUT_CUT_HEAD, LAYOUT_OK, chunk_layout, skip_mask

FRAME_HEAD = struct.Struct("<BQ")
MESSAGE_HEAD = struct.Struct("<HIQQ")


def python_walk(data: bytes, skip: set[int]) -> tuple[list[tuple[int, int, int]], int, int]:
    """The reference: what the reader did record by record before the kernel."""
    rows: list[tuple[int, int, int]] = []
    position = 0
    while position < len(data):
        if position + FRAME_HEAD.size > len(data):
            return rows, LAYOUT_CUT_HEAD, position
        opcode, length = FRAME_HEAD.unpack_from(data, position)
        start = position + FRAME_HEAD.size
        end = start + length
        if end > len(data):
            return rows, LAYOUT_CUT_BODY, position
        if (
            opcode == 0x05
            and length >= MESSAGE_HEAD.size
            and MESSAGE_HEAD.unpack_from(data, start)[0] in skip
        ):
            position = end
            continue
        rows.append((start, end, opcode))
        position = end
    return rows, LAYOUT_OK, position


def message(channel: int, payload: bytes = b"{}") -> bytes:
    body = MESSAGE_HEAD.pack(channel, 7, 1_000, 1_000) + payload
    return FRAME_HEAD.pack(0x05, len(body)) + body


def record(opcode: int, body: bytes) -> bytes:
    return FRAME_HEAD.pack(opcode, len(body)) + body


def kernel_walk(data: bytes, skip: set[int]) -> tuple[list[tuple[int, int, int]], int, int]:
    rows, status, offset = chunk_layout(data, skip_mask(skip))
    return [tuple(row) for row in rows.tolist()], status, offset


def test_skipped_channels_are_left_out_and_the_rest_kept_in_file_order():
    data = message(1) + record(0x04, b"channel") + message(2, b"x" * 40) + message(1) + message(3)
    rows, status, _ = kernel_walk(data, {1})
    assert status == LAYOUT_OK
    assert [opcode for _, _, opcode in rows] == [0x04, 0x05, 0x05]
    assert [data[start : start + 2] for start, _, opcode in rows if opcode == 0x05] == [
        b"\x02\x00",
        b"\x03\x00",
    ]
    assert kernel_walk(data, {1}) == python_walk(data, {1})


def test_a_short_message_is_kept_for_the_parser_to_name_even_on_a_skipped_channel():
    short = record(0x05, b"\x01\x00\x00")  # channel 1, but no room for the 22-byte message head
    rows, status, _ = kernel_walk(short + message(1), {1})
    assert status == LAYOUT_OK and rows == [(9, 12, 0x05)]


def test_cuts_inside_a_head_and_inside_a_body_say_where():
    whole = message(1) + message(2)
    assert kernel_walk(whole[:-3], set()) == python_walk(whole[:-3], set())
    assert kernel_walk(whole[:-3], set())[1:] == (LAYOUT_CUT_BODY, len(message(1)))
    cut_head = message(1) + b"\x05\x00\x00"
    assert kernel_walk(cut_head, set())[1:] == (LAYOUT_CUT_HEAD, len(message(1)))


def test_a_corrupt_length_near_two_to_the_64_is_a_cut_not_a_wrap_around():
    data = FRAME_HEAD.pack(0x05, 2**64 - 1) + b"\x00" * 30
    assert kernel_walk(data, set()) == ([], LAYOUT_CUT_BODY, 0)
    data = FRAME_HEAD.pack(0x05, 2**55) + b"\x00" * 30  # top byte zero, still far past the end
    assert kernel_walk(data, set()) == ([], LAYOUT_CUT_BODY, 0)


def test_an_empty_chunk_has_no_records():
    assert kernel_walk(b"", {1}) == ([], LAYOUT_OK, 0)


def test_channel_ids_past_the_skip_mask_are_kept():
    assert skip_mask({3}).tolist() == [False, False, False, True]
    assert np.array_equal(skip_mask(set()), np.zeros(0, dtype=bool))
    rows, _, _ = kernel_walk(message(65_535), {3})
    assert len(rows) == 1


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.builds(message, st.integers(0, 6), st.binary(max_size=30)),
            st.builds(record, st.integers(0, 255), st.binary(max_size=30)),
        ),
        max_size=12,
    ),
    st.integers(0, 40),
    st.sets(st.integers(0, 6)),
    st.binary(max_size=12),
)
def test_the_kernel_walks_any_bytes_as_the_python_walk_does(records, cut, skip, garbage):
    data = b"".join(records)
    data = data[: max(0, len(data) - cut)] + garbage
    assert kernel_walk(data, skip) == python_walk(data, skip)
