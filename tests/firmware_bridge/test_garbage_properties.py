"""Property tests: whatever garbage arrives, nothing raises out of a link, it is counted, and the valid
traffic after it still gets through."""

import itertools

import can
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.can_link import CanLink
from firmware_bridge.mavlink_link import GpsFix, MavlinkLink
from firmware_bridge.mavlink_transport import memory_pipe_pair
from logs.clock import SimClock
from logs.sink import MemorySink
from tests.firmware_bridge.virtual_can import make_codec

PROPERTY = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
_channels = itertools.count()
CODEC = make_codec()
VALID_STATUS = [CODEC.encode("STATUS", cid, erpm=1000 * cid, current=1.5, duty=0.25) for cid in range(1, 7)]


def mutated(msg: can.Message, flip_bit: int, cut: int) -> can.Message:
    data = bytearray(msg.data)
    data[(flip_bit // 8) % len(data)] ^= 1 << (flip_bit % 8)
    data = data[: len(data) - cut]
    return can.Message(
        arbitration_id=msg.arbitration_id, is_extended_id=True, data=bytes(data), dlc=len(data)
    )


random_frame = st.builds(
    lambda can_id, extended, data, error, remote: can.Message(
        arbitration_id=can_id if extended else can_id & 0x7FF,
        is_extended_id=extended,
        data=b"" if remote else data,
        dlc=len(data),
        is_error_frame=error,
        is_remote_frame=remote and not error,
    ),
    st.integers(0, 0x1FFFFFFF)
    | st.sampled_from([(k << 8) | c for k in (3, 9, 14, 15, 16, 27) for c in range(8)]),
    st.booleans(),
    st.binary(max_size=8),
    st.booleans(),
    st.booleans(),
)
mutated_valid = st.builds(mutated, st.sampled_from(VALID_STATUS), st.integers(0, 63), st.integers(0, 8))


@PROPERTY
@given(garbage=st.lists(random_frame | mutated_valid, max_size=40))
def test_can_garbage_is_counted_and_valid_status_after_it_is_delivered(garbage):
    channel = f"prop-{next(_channels)}"
    ours = can.Bus(interface="virtual", channel=channel, ignore_config=True)
    theirs = can.Bus(interface="virtual", channel=channel, ignore_config=True)
    try:
        link = CanLink(ours, make_codec(), SimClock(), MemorySink())
        for msg in garbage:
            theirs.send(msg)
        link.poll()
        for msg in VALID_STATUS:
            theirs.send(msg)
        link.poll()
        c = link.counters
        errors = sum(m.is_error_frame for m in garbage)
        assert c.bus_errors == errors
        assert c.rx == len(garbage) - errors + 6
        rejected = c.unknown_id + c.wrong_dlc + c.decode_errors
        assert rejected <= len(garbage) - errors
        assert [r.erpm for r in link.readings()] == [1000.0 * cid for cid in range(1, 7)]
        assert [r.motor_current_a for r in link.readings()] == [1.5] * 6
    finally:
        ours.shutdown()
        theirs.shutdown()


def gps(lat_e7: int) -> bytes:
    msg = mavlink2.MAVLink_gps_raw_int_message(0, 3, lat_e7, 85455940, 488000, 150, 300, 250, 9000, 12)
    return bytes(msg.pack(mavlink2.MAVLink(None, 1, 1)))


VALID_MAVLINK = gps(473977420)
_LONGEST_FRAME = 280  # MAVLink 2: 10 header + 255 payload + 2 CRC + 13 signature


def damage(frame: bytes, flips: list[int], cut: int) -> bytes:
    data = bytearray(frame)
    for bit in flips:
        data[(bit // 8) % len(data)] ^= 1 << (bit % 8)
    return bytes(data[: max(1, len(data) - cut)])


damaged_frame = st.builds(
    damage, st.just(VALID_MAVLINK), st.lists(st.integers(0, 8 * 60), max_size=3), st.integers(0, 40)
)
start_markers = st.lists(
    st.sampled_from([b"\xfd", b"\xfe", b"\xfd\xff", b"\xfe\xff"]) | st.binary(max_size=12)
)


@PROPERTY
@given(pieces=st.lists(damaged_frame | st.binary(max_size=64) | start_markers.map(b"".join), max_size=12))
def test_mavlink_garbage_is_counted_and_valid_frames_after_it_are_delivered(pieces):
    companion, autopilot = memory_pipe_pair()
    link = MavlinkLink(companion, SimClock(), MemorySink())
    garbage = b"".join(pieces)
    autopilot.write(garbage)
    link.poll()
    # A stray header naming a message id this dialect does not know cannot be CRC-checked, so it may take
    # up to one longest frame (280 bytes) of what follows, exactly as a real unknown message would; every
    # valid frame that starts beyond that reach must be delivered.
    valid = [gps(i + 1) for i in range(12)]
    autopilot.write(b"".join(valid))
    readings = [r for r in link.poll() if isinstance(r, GpsFix)]
    delivered = {round(r.lat_deg * 1e7) for r in readings}
    beyond_reach = {i + 1 for i in range(12) if i * len(VALID_MAVLINK) >= _LONGEST_FRAME}
    assert beyond_reach <= delivered
    if garbage:
        assert link.counters.bad_bytes > 0 or link.counters.rx_frames > len(readings)
