"""The link's hot paths read and record exactly what the plain ones do.

It decodes whole frames at the start of a read without pymavlink's byte-stream parser
(``MavlinkLink._decode_whole_frames``): whatever arrives, it must read what the parser alone reads (the
same records, readings and counters). And it formats each mavlink/raw record straight to JSON for a sink
that records bytes alone (``_raw_json``): the bytes must be the encoder's."""

import base64
import dataclasses
import itertools
import re

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_link import _DIALECT_NAMES, MavlinkLink, _raw_json, _raw_record
from firmware_bridge.mavlink_transport import memory_pipe_pair
from logs.clock import SimClock
from logs.encoding import encode_message
from logs.sink import MemorySink
from logs.topics import MAVLINK_RAW

PROPERTY = settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _packed(msg: mavlink2.MAVLink_message, *, mavlink1: bool = False, signed: bool = False) -> bytes:
    mav = mavlink2.MAVLink(None, 1, 1)
    if signed:
        mav.signing.secret_key = bytes(range(32))
        mav.signing.sign_outgoing = True
    return bytes(msg.pack(mav, force_mavlink1=mavlink1))


def _with_unknown_id(frame: bytes) -> bytes:
    """A well-formed frame of a message id the dialect does not know (pymavlink decodes it as unknown)."""
    data = bytearray(frame)
    data[7:10] = (60_123).to_bytes(3, "little")
    return bytes(data)


GPS = mavlink2.MAVLink_gps_raw_int_message(5, 3, 473977420, 85455940, 488000, 150, 300, 250, 9000, 12)
IMU = mavlink2.MAVLink_scaled_imu_message(10, 1, -2, -1000, 3, 4, -5, 0, 0, 0, 0)
HEARTBEAT = mavlink2.MAVLink_heartbeat_message(10, 3, 0, 0, 4, 3)
ATTITUDE = mavlink2.MAVLink_attitude_message(20, 0.1, -0.2, 1.5, 0.0, 0.0, 0.3)
VALID = [_packed(m) for m in (GPS, IMU, HEARTBEAT, ATTITUDE)]
ODD = [_packed(IMU, mavlink1=True), _packed(GPS, signed=True), _with_unknown_id(_packed(IMU))]


def _damaged(frame: bytes, flip: int, cut: int) -> bytes:
    data = bytearray(frame)
    data[flip % len(data)] ^= 0x5A
    return bytes(data[: max(1, len(data) - cut)])


pieces = st.lists(
    st.sampled_from(VALID)
    | st.sampled_from(ODD)
    | st.builds(_damaged, st.sampled_from(VALID), st.integers(0, 60), st.integers(0, 3))
    | st.binary(max_size=16),
    max_size=10,
)


def _read(chunks: list[bytes], *, whole_frames: bool) -> tuple[list, list, dict[str, int]]:
    companion, autopilot = memory_pipe_pair()
    sink = MemorySink()
    link = MavlinkLink(companion, SimClock(), sink)
    if not whole_frames:
        # The reference: every byte through pymavlink's parse_char, as before the whole-frame decoding.
        link._decode_whole_frames = lambda data, messages: 0  # type: ignore[method-assign]
    readings = []
    for chunk in chunks:
        autopilot.write(chunk)
        readings += link.poll()
    return sink.records, readings, dataclasses.asdict(link.counters)


@PROPERTY
@given(pieces=pieces, cuts=st.lists(st.integers(0, 400), max_size=4))
def test_whole_frame_decoding_reads_what_the_byte_parser_reads(pieces, cuts):
    stream = b"".join(pieces)
    bounds = sorted({0, len(stream), *(c for c in cuts if c < len(stream))})
    chunks = [stream[a:b] for a, b in itertools.pairwise(bounds)]
    assert _read(chunks, whole_frames=True) == _read(chunks, whole_frames=False)


def test_a_read_of_whole_frames_is_decoded_without_the_byte_parser(monkeypatch):
    companion, autopilot = memory_pipe_pair()
    link = MavlinkLink(companion, SimClock(), MemorySink())
    calls = []
    parse_char = link._mav.parse_char
    monkeypatch.setattr(link._mav, "parse_char", lambda data: calls.append(data) or parse_char(data))
    autopilot.write(b"".join(VALID))
    readings = link.poll()
    assert [type(r).__name__ for r in readings] == ["GpsFix", "ImuSample", "AttitudeSample"]  # + HEARTBEAT
    assert calls == []
    assert link.counters.rx_frames == 4


def test_every_dialect_name_needs_no_json_escape():
    assert all(re.fullmatch(r"[A-Z0-9_]+", name) for name in _DIALECT_NAMES)
    assert {"SCALED_IMU", "GPS_RAW_INT", "HEARTBEAT"} <= _DIALECT_NAMES


@PROPERTY
@given(
    t_ns=st.integers(0, 2**63 - 1),
    direction=st.sampled_from(["rx", "tx"]),
    msgid=st.integers(0, 2**24 - 1),
    name=st.sampled_from(sorted(_DIALECT_NAMES)),
    sysid=st.integers(0, 255),
    compid=st.integers(0, 255),
    frame=st.binary(max_size=280),
)
def test_raw_record_json_is_the_encoders_bytes(t_ns, direction, msgid, name, sysid, compid, frame):
    data = base64.b64encode(frame).decode("ascii")
    record = _raw_record(t_ns, direction, msgid, name, sysid, compid, data)
    assert _raw_json(t_ns, direction, msgid, name, sysid, compid, data) == encode_message(record)


class _BytesRecorder:
    """A sink that records bytes alone, as the MCAP recorder does."""

    records_bytes_only = True

    def __init__(self) -> None:
        self.records: list[tuple[str, int, bytes]] = []

    def publish(self, topic, log_time_ns, message):
        self.records.append((topic, log_time_ns, encode_message(message)))

    def publish_bytes(self, topic, log_time_ns, data):
        self.records.append((topic, log_time_ns, data))


def test_a_bytes_sink_records_what_a_message_sink_records():
    stream = b"".join([*VALID, *ODD, b"\x00garbage"])

    def recorded(sink):
        companion, autopilot = memory_pipe_pair()
        link = MavlinkLink(companion, SimClock(), sink)
        autopilot.write(stream)
        link.poll()
        link.send_heartbeat()
        return sink

    as_bytes = recorded(_BytesRecorder()).records
    as_messages = [(topic, t, encode_message(m)) for topic, t, m in recorded(MemorySink()).records]
    assert as_bytes == as_messages
    assert sum(topic == MAVLINK_RAW for topic, _, _ in as_bytes) == len(VALID) + len(ODD) + 1
