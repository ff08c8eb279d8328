"""Unsigned MAVLink 2 frames of plain messages, packed and decoded from pymavlink's own message definitions
without the per-frame work of its general paths that such a frame never needs.

pymavlink's ``MAVLink.decode`` and ``MAVLink.send`` serve every frame: MAVLink 1 and 2, signed or not,
fields in arrays or strings, fields whose wire order differs from the declared one. For each frame decode
unpacks the header with a struct, checks the signing state, builds a CRC object, reorders the fields in a
Python loop, looks for strings to terminate, builds the message (whose constructor builds a header object
that is dropped at once for a second one) and sets attributes that stay constant on an unsigned link; send
packs through the message's ``_pack``, which converts the protocol version from its text twice, builds a
header object and two CRC objects and stamps the message with the frame. The simulated autopilot's frames
(~70 a simulated second, each packed once by it and decoded once by the rover's link) are all of the plain
kind: unsigned MAVLink 2, messages without arrays or text. For those ``send_unsigned_v2`` writes the bytes
``send`` writes (the same header, the payload's trailing zeros dropped, the CRC with the message's CRC
extra through pymavlink's own CRC function) and ``decode_unsigned_v2`` checks what ``decode`` checks and
builds the same message object (class, fields, header, buffers, CRC) from the same message class and its
struct. Any other frame or message, and a received frame whose CRC does not match, goes to pymavlink's
general path, which handles it (or names the refusal) as always. ``tests/firmware_bridge/
test_mavlink_frames.py`` compares both ways on every plain message of the dialect.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from operator import attrgetter, itemgetter
from typing import Any, NamedTuple

from pymavlink.dialects.v20 import common as mavlink2

_V2_HEADER_LEN = 10
V2_FRAME_OVERHEAD = 12  # MAVLink 2: the header and a 2-byte CRC around the payload
_V2_HEADER = struct.Struct("<BBBBBBBHB")  # marker, length, incompat and compat flags, seq, ids, msgid


class _PlainMessage(NamedTuple):
    """What packing or decoding one message type's frames needs, looked up once per frame."""

    cls: type[mavlink2.MAVLink_message]
    msgid: int
    crc_extra: bytes  # the message's CRC extra, the byte its CRC covers after the frame
    unpacker: struct.Struct
    # The fields in declared order from the wire's (size-sorted) order; None when the two are the same.
    reorder: Callable[[tuple[Any, ...]], tuple[Any, ...]] | None
    # A message's fields in wire order (None for a message of one field: such go the general way).
    wire_fields: Callable[[Any], tuple[Any, ...]] | None


def _is_plain(cls: type[mavlink2.MAVLink_message]) -> bool:
    """No arrays and no text: the fields are the unpacked values, reordered (``MAVLink.decode``'s case of
    a message "with no arrays in it", with no string to terminate)."""
    return sum(cls.lengths) == len(cls.lengths) and "char" not in cls.fieldtypes


def _plain_message(cls: type[mavlink2.MAVLink_message]) -> _PlainMessage:
    orders = list(cls.orders)
    reorder = None if orders == sorted(orders) or len(orders) < 2 else itemgetter(*orders)
    names = cls.ordered_fieldnames
    wire_fields = attrgetter(*names) if len(names) > 1 else None
    return _PlainMessage(cls, cls.id, bytes((cls.crc_extra,)), cls.unpacker, reorder, wire_fields)


# Without fastcrc pymavlink computes CRCs in Python: then every frame goes its general way.
_ALL_PLAIN = (
    []
    if mavlink2.mcrf4xx is None
    else [_plain_message(cls) for cls in mavlink2.mavlink_map.values() if _is_plain(cls)]
)
# Received frames by message id; MAV_IGNORE_CRC (pymavlink's switch to skip the check) leaves all to decode.
_PLAIN = {} if mavlink2.MAVLINK_IGNORE_CRC else {plain.msgid: plain for plain in _ALL_PLAIN}
# Messages to send by class.
_PLAIN_BY_CLASS = {plain.cls: plain for plain in _ALL_PLAIN if plain.wire_fields is not None}


def send_unsigned_v2(mav: mavlink2.MAVLink, msg: Any) -> None:
    """``mav.send(msg)``: the same bytes written to ``mav.file``, the same sequence number and counts after,
    for a plain message on a link that signs nothing and has no send callback (any other goes to
    ``mav.send``). Unlike ``mav.send`` it leaves ``msg`` as it was, not stamped with the frame: for a
    sender that keeps no sent message (the simulated autopilot)."""
    plain = _PLAIN_BY_CLASS.get(type(msg))
    if plain is None or plain.wire_fields is None or mav.signing.sign_outgoing or mav.send_callback:
        mav.send(msg)
        return
    payload = plain.unpacker.pack(*plain.wire_fields(msg))
    # MAVLink 2 drops the payload's trailing zeros, keeping one byte at least.
    payload = payload.rstrip(b"\x00") or payload[:1]
    msgid = plain.msgid
    header = _V2_HEADER.pack(
        mavlink2.PROTOCOL_MARKER_V2,
        len(payload),
        0,
        0,
        mav.seq,
        mav.srcSystem,
        mav.srcComponent,
        msgid & 0xFFFF,
        msgid >> 16,
    )
    crc = mavlink2.mcrf4xx(header[1:] + payload + plain.crc_extra, 0xFFFF)
    frame = header + payload + crc.to_bytes(2, "little")
    mav.file.write(frame)
    mav.seq = (mav.seq + 1) % 256
    mav.total_packets_sent += 1
    mav.total_bytes_sent += len(frame)


def decode_unsigned_v2(frame: bytearray, decode: Callable[[bytearray], Any]) -> Any:
    """The message of one whole ``frame``, as ``decode`` (a ``MAVLink.decode``) makes it, which decodes any
    frame but an unsigned MAVLink 2 frame of a plain message with a matching CRC; ``frame`` is kept in the
    message (``get_msgbuf``), as ``decode`` keeps it.

    Only for a ``MAVLink`` without a signing key: with one, ``decode`` asks its allow-unsigned callback
    about every unsigned frame, so such a frame must go there (the link calls this only without a key)."""
    size = len(frame)
    plain = _PLAIN.get(frame[7] | frame[8] << 8 | frame[9] << 16) if size >= V2_FRAME_OVERHEAD else None
    if (
        plain is None
        or frame[0] != mavlink2.PROTOCOL_MARKER_V2
        or frame[2] != 0  # incompat flags: signed, or a flag this version does not know
        or frame[1] != size - V2_FRAME_OVERHEAD
    ):
        return decode(frame)
    crc = frame[-2] | frame[-1] << 8
    if mavlink2.mcrf4xx(frame[1:-2] + plain.crc_extra, 0xFFFF) != crc:
        return decode(frame)  # refused there, in its words
    unpacker = plain.unpacker
    payload = frame[_V2_HEADER_LEN:-2]
    if len(payload) != unpacker.size:
        # MAVLink 2 drops a payload's trailing zeros; fields past the known ones are ignored.
        payload = payload.ljust(unpacker.size, b"\x00")[: unpacker.size]
    values = unpacker.unpack(payload)
    msg = plain.cls(*(values if plain.reorder is None else plain.reorder(values)))
    # What decode sets after construction, but for _signed and _link_id (an unsigned frame leaves them at
    # the constructor's False and None), and the header is the constructor's, filled in, not a second one.
    msg._msgbuf = frame
    msg._payload = frame[6:-2]  # sic: decode slices the payload from 6 in MAVLink 2 frames too
    msg._crc = crc
    header = msg._header  # msgId set, incompat flags 0
    header.compat_flags, header.mlen, header.seq = frame[3], frame[1], frame[4]
    header.srcSystem, header.srcComponent = frame[5], frame[6]
    return msg
