"""The plain-message fast paths (``firmware_bridge.mavlink_frames``) equal pymavlink's general ones.

``send_unsigned_v2`` must write what ``MAVLink.send`` writes and leave the same sequence number and counts;
``decode_unsigned_v2`` must build the message ``MAVLink.decode`` builds, attribute for attribute, and leave
every other frame (a damaged one included) to ``decode``. Both are checked on every plain message of the
dialect, with random field values (zeros often, for the payload's dropped trailing zeros) and random
payload lengths (MAVLink 2 senders may cut or extend a payload)."""

import io
import random
import struct

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_frames import _PLAIN, _PLAIN_BY_CLASS, decode_unsigned_v2, send_unsigned_v2

_INTEGER_BITS = {"int8_t": 8, "int16_t": 16, "int32_t": 32, "int64_t": 64}


def _random_value(rnd: random.Random, fieldtype: str) -> int | float:
    if rnd.random() < 0.4:
        return 0
    kind = fieldtype.removesuffix("_mavlink_version")
    if kind in ("float", "double"):
        return rnd.choice([rnd.uniform(-1e6, 1e6), rnd.uniform(-1.0, 1.0), float("nan"), -0.0])
    signed = not kind.startswith("u")
    bits = _INTEGER_BITS[kind.removeprefix("u")]
    return rnd.randint(-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else rnd.randint(0, 2**bits - 1)


def _random_message(rnd: random.Random, cls: type[mavlink2.MAVLink_message]) -> mavlink2.MAVLink_message:
    return cls(*(_random_value(rnd, fieldtype) for fieldtype in cls.fieldtypes))


def _state(msg: mavlink2.MAVLink_message) -> str:
    """Every attribute of a message, its header's too (repr: NaN equals NaN, -0.0 differs from 0.0)."""
    attributes = dict(vars(msg))
    attributes["_header"] = vars(msg.get_header())
    return repr(attributes)


def _frame(rnd: random.Random, msgid: int, payload: bytes, crc_extra: int) -> bytearray:
    """A MAVLink 2 frame of ``payload`` with random sequence, ids and compat flags and a correct CRC."""
    head = bytes([0xFD, len(payload), 0, *(rnd.getrandbits(8) for _ in range(4))])
    body = head + msgid.to_bytes(3, "little") + payload
    crc = mavlink2.x25crc(bytearray(body[1:]) + bytes([crc_extra])).crc
    return bytearray(body + crc.to_bytes(2, "little"))


def test_the_simulated_autopilots_messages_are_plain():
    for cls in (
        mavlink2.MAVLink_scaled_imu_message,
        mavlink2.MAVLink_attitude_message,
        mavlink2.MAVLink_gps_raw_int_message,
        mavlink2.MAVLink_sys_status_message,
        mavlink2.MAVLink_heartbeat_message,
    ):
        assert cls in _PLAIN_BY_CLASS
        assert cls.id in _PLAIN
    assert mavlink2.MAVLINK_MSG_ID_BATTERY_STATUS not in _PLAIN  # an array: the general path


@pytest.mark.parametrize("start_seq", [0, 254])
def test_send_writes_what_pymavlink_sends(start_seq):
    rnd = random.Random(start_seq)
    for cls in _PLAIN_BY_CLASS:
        for _ in range(8):
            msg = _random_message(rnd, cls)
            general, fast = io.BytesIO(), io.BytesIO()
            mav_general = mavlink2.MAVLink(general, 7, 191)
            mav_fast = mavlink2.MAVLink(fast, 7, 191)
            mav_general.seq = mav_fast.seq = start_seq
            for _ in range(3):  # the sequence number wraps past 255
                mav_general.send(msg)
                send_unsigned_v2(mav_fast, msg)
            assert fast.getvalue() == general.getvalue(), cls.msgname
            assert (mav_fast.seq, mav_fast.total_packets_sent, mav_fast.total_bytes_sent) == (
                mav_general.seq,
                mav_general.total_packets_sent,
                mav_general.total_bytes_sent,
            )


def test_send_signs_and_calls_back_through_pymavlink():
    msg = mavlink2.MAVLink_heartbeat_message(10, 3, 0, 0, 4, 3)
    written = []
    for mav in (mavlink2.MAVLink(io.BytesIO(), 1, 1), mavlink2.MAVLink(io.BytesIO(), 1, 1)):
        mav.signing.secret_key = bytes(range(32))
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = 1234
        written.append(mav)
    written[0].send(msg)
    send_unsigned_v2(written[1], msg)
    assert written[1].file.getvalue() == written[0].file.getvalue()
    assert written[1].file.getvalue()[2] & mavlink2.MAVLINK_IFLAG_SIGNED
    called = []
    mav = mavlink2.MAVLink(io.BytesIO(), 1, 1)
    mav.set_send_callback(lambda sent: called.append(sent))
    send_unsigned_v2(mav, msg)
    assert called == [msg]


def test_decode_builds_what_pymavlink_decodes():
    rnd = random.Random(5)
    mav = mavlink2.MAVLink(None, 1, 1)
    for msgid, plain in _PLAIN.items():
        size = plain.unpacker.size
        for length in {0, 1, size // 2, size - 1, size, size + 3}:  # cut or extended payloads
            payload = bytes(rnd.getrandbits(8) for _ in range(length))
            frame = _frame(rnd, msgid, payload, plain.cls.crc_extra)
            expected = mavlink2.MAVLink(None, 1, 1).decode(frame[:])
            assert _state(decode_unsigned_v2(frame[:], mav.decode)) == _state(expected), plain.cls.msgname


def test_decode_of_sent_frames_reads_the_message_sent():
    rnd = random.Random(6)
    for cls in _PLAIN_BY_CLASS:
        out = io.BytesIO()
        msg = _random_message(rnd, cls)
        send_unsigned_v2(mavlink2.MAVLink(out, 1, 1), msg)
        decoded = decode_unsigned_v2(bytearray(out.getvalue()), mavlink2.MAVLink(None, 1, 1).decode)
        expected = mavlink2.MAVLink(None, 1, 1).decode(bytearray(out.getvalue()))
        assert _state(decoded) == _state(expected)
        assert type(decoded) is cls


def test_decode_leaves_other_frames_to_pymavlink():
    rnd = random.Random(7)
    imu = mavlink2.MAVLink_scaled_imu_message(10, 1, -2, -1000, 3, 4, -5, 0, 0, 0, 0)
    good = _frame(rnd, imu.id, bytes(imu.pack(mavlink2.MAVLink(None, 1, 1)))[10:-2], imu.crc_extra)
    bad_crc = good[:]
    bad_crc[-1] ^= 0x40
    bad_length = good[:]
    bad_length[1] += 1
    signed_mav = mavlink2.MAVLink(None, 1, 1)
    signed_mav.signing.secret_key = bytes(32)
    signed_mav.signing.sign_outgoing = True
    signed = bytearray(imu.pack(signed_mav))
    battery = mavlink2.MAVLink_battery_status_message(0, 0, 0, 250, [3700] * 10, 100, -1, -1, 80)
    array = bytearray(battery.pack(mavlink2.MAVLink(None, 1, 1)))
    v1 = bytearray(imu.pack(mavlink2.MAVLink(None, 1, 1), force_mavlink1=True))
    for frame in (bad_crc, bad_length, signed, array, v1, bytearray(b"\xfd\x00")):
        seen = []

        def decode(data, seen=seen):
            seen.append(bytes(data))
            return mavlink2.MAVLink(None, 1, 1).decode(data)

        try:
            expected = _state(mavlink2.MAVLink(None, 1, 1).decode(frame[:]))
        except (mavlink2.MAVError, struct.error, IndexError) as err:
            with pytest.raises(type(err)) as raised:
                decode_unsigned_v2(frame[:], decode)
            assert str(raised.value) == str(err)
        else:
            assert _state(decode_unsigned_v2(frame[:], decode)) == expected
        assert seen == [bytes(frame)]  # handed over whole, as it came
