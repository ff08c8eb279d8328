"""Precomputed ``struct`` packers for DBC messages whose layout allows one: the hot-path frame codec.

A lockstep trial encodes and decodes ~720 VESC frames per simulated second (six SET_RPM per 20 ms control
tick; from the simulated controllers six STATUS per 20 ms and six each of STATUS_4 and STATUS_5 per
100 ms). cantools' ``Message.encode(..., strict=False)`` walks its signal tables per call (~2 us a STATUS
frame, measured on the build VM); a ``struct.Struct`` built once from the same DBC message packs the same
bytes in ~0.9 us, and unpacks them in ~0.9 us against cantools' ~1.4 us.

The packer is derived from the cantools message itself, never from our own protocol table, so a swapped DBC
profile is followed or, when its layout is not plain (little-endian, not byte-aligned, odd widths, floats,
multiplexed, choices), ``FramePacker.for_message`` returns ``None`` and callers stay with cantools.
Values go through the signal's own cantools conversion (``numeric_scaled_to_raw``), so rounding and
scaling are cantools' to the last bit; a test compares both on random values (``packing``, the senders'
hot path, writes out ``LinearConversion``'s one expression instead of calling it). Decoding computes
``raw * scale + offset`` with the conversion's own scale and offset: that expression is the whole of
``raw_to_scaled`` in each of the three conversion classes a packer accepts (Identity's scale and offset
are 1 and 0), and inlined it costs half of calling it per field (a test compares the numbers on random
payloads).

What ``pack`` does NOT do is cantools' range checking: it is the equivalent of
``encode(..., strict=False)`` for values already in range (a raw value outside its field falls back to
cantools, which then behaves as it always does). ``unpack`` takes data of exactly the message's length:
``VescCodec.decode`` checks the id, format and length first, as it does before cantools' decode.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import can
import cantools.database
from cantools.database.conversion import IdentityConversion, LinearConversion, LinearIntegerConversion

_CODES = {(8, True): "b", (8, False): "B", (16, True): "h", (16, False): "H"}
_CODES |= {(32, True): "i", (32, False): "I", (64, True): "q", (64, False): "Q"}
# Exactly these classes (not subclasses): unpack relies on how they scale (raw * scale + offset).
_PLAIN_CONVERSIONS = (IdentityConversion, LinearIntegerConversion, LinearConversion)


class FramePacker:
    """One DBC message as a big-endian ``struct`` of whole-byte integer fields (gaps packed as zero)."""

    def __init__(self, message: cantools.database.can.Message, layout: str, signals: tuple[Any, ...]) -> None:
        self.message = message
        self._struct = struct.Struct(layout)
        # (name, physical -> raw) per field in struct order: one tuple walked per pack.
        self._fields = tuple((signal.name, _to_raw(signal.conversion)) for signal in signals)
        self._conversions = tuple(signal.conversion for signal in signals)
        self._lengths = tuple(signal.length for signal in signals)  # in bits
        # (name, scale, offset) per field in struct order: raw_to_scaled's arithmetic, without its call.
        self._scaling = tuple(
            (signal.name, signal.conversion.scale, signal.conversion.offset) for signal in signals
        )

    @classmethod
    def for_message(cls, message: cantools.database.can.Message) -> FramePacker | None:
        """The packer for ``message``, or ``None`` when its layout is not one ``struct`` can express."""
        if message.is_container or message.is_multiplexed() or not message.signals:
            return None
        placed = []
        for signal in message.signals:
            code = _CODES.get((signal.length, signal.is_signed))
            if (
                code is None
                or signal.byte_order != "big_endian"
                or signal.conversion.is_float
                or signal.conversion.choices
                or type(signal.conversion) not in _PLAIN_CONVERSIONS
                or signal.start % 8 != 7  # Motorola start bit = the MSB; byte-aligned means bit 7 of a byte
            ):
                return None
            placed.append((signal.start // 8, signal.length // 8, code, signal))
        placed.sort(key=lambda item: item[0])
        layout = ">"
        position = 0
        for first_byte, width, code, _ in placed:
            if first_byte < position:
                return None  # overlapping signals
            layout += "x" * (first_byte - position) + code
            position = first_byte + width
        if position > message.length:
            return None
        layout += "x" * (message.length - position)
        return cls(message, layout, tuple(signal for _, _, _, signal in placed))

    def pack(self, values: Mapping[str, float]) -> bytes:
        """The frame's data bytes, as cantools ``encode(values, strict=False)`` gives them."""
        raws = [to_raw(values[name]) for name, to_raw in self._fields]
        try:
            return self._struct.pack(*raws)
        except struct.error:
            # A raw value outside its field: whatever cantools does with it (its own error, or its packing).
            return bytes(self.message.encode(dict(values), strict=False))

    def unpack(self, data: bytes | bytearray) -> dict[str, float]:
        """Signal name -> physical value (a float) for data of exactly the message's length."""
        # Hot path (every received VESC frame): see the module's docstring for why this is cantools' number.
        raws = self._struct.unpack(data)
        return {
            name: float(raw * scale + offset)
            for (name, scale, offset), raw in zip(self._scaling, raws, strict=True)
        }

    def packing(self, names: Sequence[str], fixed: Mapping[str, float]) -> Callable[[Sequence[float]], bytes]:
        """A function from the physical values of ``names``, in that order, to the frame's data bytes, the
        message's other signals held at ``fixed``: ``pack``'s bytes for the same values (the same
        conversions; the fixed ones made once, here), without a dict per frame.

        For a sender of the same message over and over with values it holds as numbers (the simulated
        controllers' status frames, the link's SET_RPM). A raw value outside its field goes to cantools, as
        in ``pack``. ``names`` and ``fixed`` name each of the message's signals once: the caller checks
        that (``FieldEncoder``, which also serves a message without a packer)."""
        # The raw values in struct order, the fixed ones filled in; per frame, (position in the struct,
        # position in the caller's values, conversion) of each of the others, the conversion given as
        # (scale, offset) alone for an integer signal of cantools' LinearConversion: its
        # numeric_scaled_to_raw is ``round((value - offset) / scale)``, inlined below as unpack inlines
        # raw_to_scaled (half the cost of the method call; the tests compare the bytes with cantools').
        template = [to_raw(fixed[name]) if name in fixed else 0 for name, to_raw in self._fields]
        variable = tuple(
            (position, names.index(name), *_inline_or_call(to_raw, conversion, length))
            for position, ((name, to_raw), conversion, length) in enumerate(
                zip(self._fields, self._conversions, self._lengths, strict=True)
            )
            if name not in fixed
        )
        pack = self._struct.pack

        def to_cantools(values: Sequence[float]) -> bytes:
            given = dict(zip(names, values, strict=True))
            return bytes(self.message.encode({**fixed, **given}, strict=False))

        written_out = _written_out(pack, to_cantools, variable, len(template))
        if written_out is not None:
            return written_out

        def pack_values(values: Sequence[float]) -> bytes:
            raws = template.copy()
            for position, index, to_raw, scale, offset in variable:
                value = values[index]
                raws[position] = round((value - offset) / scale) if to_raw is None else to_raw(value)
            try:
                return pack(*raws)
            except struct.error:
                return to_cantools(values)

        return pack_values

    def frame_reader(self, names: Sequence[str]) -> Callable[[can.Message], list[float] | None]:
        """A function from a received frame to the physical values of ``names``, in that order, or None when
        the frame is not in this message's format (its id's width, not remote, dlc and data of the
        message's length): ``unpack``'s numbers (the same expression) without its dict.

        For a receiver that reads a few fields of every frame on a hot path (the CAN link's status frames,
        the simulated controllers' SET_RPM): one call and one list per frame, the format checked in it."""
        index = {name: i for i, (name, _, _) in enumerate(self._scaling)}
        missing = [name for name in names if name not in index]
        if missing:
            raise ValueError(f"{self.message.name} has no signal {', '.join(missing)}")
        picks = tuple((index[name], *_float_identity(*self._scaling[index[name]][1:])) for name in names)
        unpack = self._struct.unpack
        extended = self.message.is_extended_frame
        length = self.message.length

        # Where every field has a float scale or offset, each expression below is a float already and
        # float() would return its argument: the same numbers without a call per field (hot path).
        floats = all(isinstance(scale, float) or isinstance(offset, float) for _, scale, offset in picks)
        if floats and 1 <= len(picks) <= 3:
            return _written_out_reader(unpack, extended, length, picks)

        def read(msg: can.Message) -> list[float] | None:
            data = msg.data
            if msg.is_extended_id != extended or msg.is_remote_frame or not msg.dlc == length == len(data):
                return None
            raws = unpack(data)
            if floats:
                return [raws[i] * scale + offset for i, scale, offset in picks]
            return [float(raws[i] * scale + offset) for i, scale, offset in picks]

        return read


def _written_out_reader(
    unpack: Callable[[bytes | bytearray], tuple[Any, ...]],
    extended: bool,
    length: int,
    picks: tuple[tuple[int, float, float], ...],
) -> Callable[[can.Message], list[float] | None]:
    """``frame_reader``'s function written out for one to three fields whose expressions are floats
    already (every VESC status and SET_RPM reader): the same checks and arithmetic, without the loop and
    the list comprehension's call per frame (hot path: every status frame and command received)."""
    if len(picks) == 1:
        ((i0, s0, o0),) = picks

        def read_one(msg: can.Message) -> list[float] | None:
            data = msg.data
            if msg.is_extended_id != extended or msg.is_remote_frame or not msg.dlc == length == len(data):
                return None
            return [unpack(data)[i0] * s0 + o0]

        return read_one
    if len(picks) == 2:
        (i0, s0, o0), (i1, s1, o1) = picks

        def read_two(msg: can.Message) -> list[float] | None:
            data = msg.data
            if msg.is_extended_id != extended or msg.is_remote_frame or not msg.dlc == length == len(data):
                return None
            raws = unpack(data)
            return [raws[i0] * s0 + o0, raws[i1] * s1 + o1]

        return read_two
    (i0, s0, o0), (i1, s1, o1), (i2, s2, o2) = picks

    def read_three(msg: can.Message) -> list[float] | None:
        data = msg.data
        if msg.is_extended_id != extended or msg.is_remote_frame or not msg.dlc == length == len(data):
            return None
        raws = unpack(data)
        return [raws[i0] * s0 + o0, raws[i1] * s1 + o1, raws[i2] * s2 + o2]

    return read_three


def _to_raw(conversion: Any) -> Callable[[float], float]:
    """The signal's physical -> raw conversion: cantools' own, but for an integer identity conversion,
    whose ``numeric_scaled_to_raw`` is ``round(value)``: the builtin saves a method call per field."""
    if isinstance(conversion, IdentityConversion) and not conversion.is_float:
        return round
    return conversion.numeric_scaled_to_raw


def _float_identity(scale: float, offset: float) -> tuple[float, float]:
    """An identity conversion's integer (1, 0) as (1.0, 0.0): ``raw * 1.0 + 0.0`` is ``float(raw)``
    exactly (the integer is rounded to a float once either way, the rest is exact), so a reader may leave
    out the float() call; any other scale and offset as they are."""
    if type(scale) is int and type(offset) is int and scale == 1 and offset == 0:
        return 1.0, 0.0
    return scale, offset


def _inline_or_call(
    to_raw: Callable[[float], float], conversion: Any, length: int
) -> tuple[Callable[[float], float] | None, float, float]:
    """(None, scale, offset) for an integer signal of exactly cantools' ``LinearConversion``, whose
    physical -> raw is ``round((value - offset) / scale)``, and (None, 1, 0) for an integer identity
    conversion of at most 32 bits, whose ``round(value)`` that expression equals wherever the result
    fits the field: a float divided by 1 is itself, and so is an int below 2**53; a larger int fits in
    neither form (the packer then asks cantools, with the value itself). Else (``to_raw``, 1, 0): call
    it."""
    if type(conversion) is LinearConversion and not conversion.is_float:
        return None, conversion.scale, conversion.offset
    if type(conversion) is IdentityConversion and not conversion.is_float and length <= 32:
        return None, 1, 0
    return to_raw, 1.0, 0.0


def _written_out(
    pack: Callable[..., bytes],
    to_cantools: Callable[[Sequence[float]], bytes],
    variable: tuple[tuple[Any, ...], ...],
    fields: int,
) -> Callable[[Sequence[float]], bytes] | None:
    """``packing``'s function written out for the messages the simulated controllers and the link send
    over and over (STATUS, STATUS_5, SET_RPM): one to three fields, each given in struct order, none held
    fixed, each converted inline (``_inline_or_call``). The same arithmetic as the loop, without the loop
    and the list it fills: a third of its cost per frame. None for any other shape (the loop)."""
    in_order = all(position == index == i for i, (position, index, *_) in enumerate(variable))
    if len(variable) != fields or not in_order or any(to_raw is not None for _, _, to_raw, _, _ in variable):
        return None
    conversions = [(scale, offset) for _, _, _, scale, offset in variable]
    if fields == 1:
        ((s0, o0),) = conversions

        def pack_one(values: Sequence[float]) -> bytes:
            try:
                return pack(round((values[0] - o0) / s0))
            except struct.error:
                return to_cantools(values)

        return pack_one
    if fields == 2:
        (s0, o0), (s1, o1) = conversions

        def pack_two(values: Sequence[float]) -> bytes:
            try:
                return pack(round((values[0] - o0) / s0), round((values[1] - o1) / s1))
            except struct.error:
                return to_cantools(values)

        return pack_two
    if fields == 3:
        (s0, o0), (s1, o1), (s2, o2) = conversions

        def pack_three(values: Sequence[float]) -> bytes:
            try:
                return pack(
                    round((values[0] - o0) / s0), round((values[1] - o1) / s1), round((values[2] - o2) / s2)
                )
            except struct.error:
                return to_cantools(values)

        return pack_three
    return None
