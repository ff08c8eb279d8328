import dataclasses
import random

import can
import pytest

from firmware_bridge.can_health import CAN_ERR_BUSOFF
from firmware_bridge.can_link import (
    _MAX_CACHED_FRAME_KINDS,
    CanConfig,
    CanLink,
    WheelStatus,
    _frame_json,
    _frame_record,
    _FrameRecords,
    open_bus,
)
from firmware_bridge.errors import BridgeOperationError, BridgeSetupError
from logs.can_load import frame_bits
from logs.clock import SimClock
from logs.encoding import encode_message
from logs.settings import ConfigError, parse_toml
from logs.sink import MemorySink
from logs.topics import CAN_FRAMES, SAFETY_EVENTS, WHEELS_STATUS
from tests.firmware_bridge.virtual_can import BUS_KINDS, TEST_PROFILE, bus_pair, make_codec


@pytest.fixture(params=BUS_KINDS)
def buses(request):
    """Each test on a virtual bus and on the lockstep one, whose link and controllers move frames in
    batches (BatchBus): the same behaviour either way."""
    with bus_pair(request.param, request.node.name) as pair:
        yield pair


def make_link(bus, clock=None, sink=None):
    return CanLink(bus, make_codec(), clock or SimClock(), sink if sink is not None else MemorySink())


def ext(can_id: int, data: bytes) -> can.Message:
    return can.Message(arbitration_id=can_id, is_extended_id=True, data=data, dlc=len(data))


def test_send_wheel_speeds_sends_six_set_rpm_frames_and_records_them(buses):
    ours, theirs = buses
    clock, sink = SimClock(5_000_000_000), MemorySink()
    link = make_link(ours, clock, sink)
    sent = link.send_wheel_speeds([1.0, 1.0, 1.0, -0.5, -0.5, 0.0])
    expected = round(TEST_PROFILE.erpm_from_speed(1.0))
    assert sent[:3] == [expected] * 3
    assert sent[5] == 0.0
    received = [theirs.recv(timeout=0) for _ in range(6)]
    assert [m.arbitration_id for m in received] == [(3 << 8) | cid for cid in range(1, 7)]
    assert int.from_bytes(received[0].data, "big", signed=True) == expected
    records = [(t, m) for topic, t, m in sink.records if topic == CAN_FRAMES]
    assert len(records) == 6
    t, first = records[0]
    assert t == 5_000_000_000
    assert first == {
        "timestamp": {"sec": 5, "nsec": 0},
        "direction": "tx",
        "id": 0x301,
        "extended": True,
        "dlc": 4,
        "data": bytes(received[0].data).hex(),
    }
    assert link.counters.tx == 6


def test_non_finite_speed_stops_that_wheel_and_is_counted(buses):
    link = make_link(buses[0])
    sent = link.send_wheel_speeds([float("nan"), 1.0, 1.0, 1.0, 1.0, float("inf")])
    assert sent[0] == 0.0 and sent[5] == 0.0
    assert link.counters.bad_commands == 2
    with pytest.raises(BridgeOperationError, match="6 wheel speeds"):
        link.send_wheel_speeds([1.0, 2.0])


def test_poll_counts_bad_frames_and_keeps_good_status(buses):
    ours, theirs = buses
    clock, sink = SimClock(1_000), MemorySink()
    link = make_link(ours, clock, sink)
    theirs.send(ext((9 << 8) | 42, bytes(8)))  # unknown controller
    theirs.send(ext((9 << 8) | 1, bytes(6)))  # wrong DLC
    theirs.send(can.Message(arbitration_id=0x7, is_extended_id=False, data=b"\x00"))  # standard id
    theirs.send(can.Message(is_error_frame=True, arbitration_id=0, is_extended_id=True))
    theirs.send(ext((9 << 8) | 2, bytes.fromhex("000004d2007b01f4")))
    theirs.send(ext((27 << 8) | 2, bytes.fromhex("00000258 00f5 0000")))
    assert link.poll() == 6
    counters = link.counters.as_dict()
    assert counters["unknown_id"] == 2
    assert counters["wrong_dlc"] == 1
    assert counters["bus_errors"] == 1
    assert counters["rx"] == 5
    wheel = link.readings()[1]
    assert wheel.erpm == 1234.0
    assert wheel.motor_current_a == pytest.approx(12.3)
    assert wheel.duty == pytest.approx(0.5)
    assert wheel.speed_mps == pytest.approx(TEST_PROFILE.speed_from_erpm(1234))
    assert wheel.tachometer == pytest.approx(100.0)
    assert wheel.input_voltage_v == pytest.approx(24.5)
    assert wheel.last_status_ns == 1_000
    assert link.readings()[0].last_status_ns is None
    statuses = sink.on(WHEELS_STATUS)
    assert len(statuses) == 1
    assert [w["controller_id"] for w in statuses[0]["wheels"]] == [1, 2, 3, 4, 5, 6]
    assert statuses[0]["wheels"][1]["erpm"] == 1234.0
    # Every frame received, in order; the error frame marked as one (the counter counts it, not rx).
    frames = sink.on(CAN_FRAMES)
    assert [m["direction"] for m in frames] == ["rx"] * 6
    assert [m.get("error", False) for m in frames] == [False, False, False, True, False, False]
    # nothing more to read: no frames, no new status message
    assert link.poll() == 0
    assert len(sink.on(WHEELS_STATUS)) == 1


def _status_of_readings(link: CanLink) -> WheelStatus:
    """``wheel_status()`` written the plain way, from ``readings()``."""
    readings = link.readings()
    return WheelStatus(
        tuple(r.last_status_ns for r in readings),
        tuple(r.speed_mps for r in readings),
        tuple(r.motor_current_a for r in readings),
        tuple(r.input_voltage_v for r in readings),
    )


def test_wheel_status_follows_the_readings_and_is_rebuilt_after_each_poll(buses):
    ours, theirs = buses
    clock = SimClock(1_000)
    link = make_link(ours, clock)
    before = link.wheel_status()
    assert before == _status_of_readings(link)
    assert before.status_ns == (None,) * 6
    assert link.wheel_status() is before  # nothing polled: the same tuples
    theirs.send(ext((9 << 8) | 2, bytes.fromhex("000004d2007b01f4")))  # STATUS of controller 2
    theirs.send(ext((27 << 8) | 2, bytes.fromhex("00000258 00f5 0000")))  # STATUS_5: 24.5 V
    assert link.poll() == 2
    after = link.wheel_status()
    assert after is not before
    assert after == _status_of_readings(link)
    assert after.status_ns[1] == 1_000 and after.speeds_mps[1] == TEST_PROFILE.speed_from_erpm(1234)
    assert after.input_voltages_v[1] == pytest.approx(24.5)
    clock.advance(1_000)
    theirs.send(ext((9 << 8) | 2, bytes.fromhex("fffffb2e007b01f4")))  # STATUS: -1234 ERPM
    assert link.poll() == 1
    assert link.wheel_status().speeds_mps[1] == TEST_PROFILE.speed_from_erpm(-1234)
    assert link.wheel_status() == _status_of_readings(link)


def test_readings_are_copies(buses):
    link = make_link(buses[0])
    link.readings()[0].erpm = 99.0
    assert link.readings()[0].erpm == 0.0


def test_readings_copy_every_field(buses):
    link = make_link(buses[0])
    # Every field set to a value no default has, so a field the copy forgets shows up as a difference.
    for index, reading in enumerate(link._readings):
        for number, field in enumerate(dataclasses.fields(reading)):
            setattr(reading, field.name, 1000 * index + number + 1)
    assert link.readings() == link._readings
    assert all(copy is not original for copy, original in zip(link.readings(), link._readings, strict=True))


def test_close_sends_zero_once_then_shuts_down_and_is_idempotent(buses):
    ours, theirs = buses
    with make_link(ours) as link:
        link.send_wheel_speeds([1.0] * 6)
    link.close()
    frames = []
    while (msg := theirs.recv(timeout=0)) is not None:
        frames.append(msg)
    assert len(frames) == 12
    assert all(bytes(m.data) == bytes(4) for m in frames[6:])
    # the bus is shut: a later send fails, is counted, and does not raise
    link.send_wheel_speeds([0.0] * 6)
    assert link.counters.bus_errors == 6


def test_can_config_from_table_and_open_bus(request):
    table = parse_toml(f'interface = "virtual"\nchannel = "cfg-{request.node.name}"', "rover.toml")
    config = CanConfig.from_table(table)
    assert config.bitrate == 1_000_000 and config.command_rate_hz == 50.0
    bus = open_bus(config)
    try:
        assert bus.channel_info
    finally:
        bus.shutdown()
    with pytest.raises(ConfigError, match="interface"):
        CanConfig.from_table(parse_toml('interface = "pcan"', "rover.toml"))
    with pytest.raises(ConfigError, match="bitrat"):
        CanConfig.from_table(parse_toml("bitrat = 500000", "rover.toml"))
    with pytest.raises(BridgeSetupError, match="interface"):
        CanConfig(interface="kvaser")


@pytest.mark.parametrize("text", ['channel = ""', 'interface = "socketcan"\nchannel = ""'])
def test_an_empty_can_channel_is_a_config_error_naming_the_key(text):
    # It was a BridgeSetupError from the dataclass, raised before from_table's own check: a traceback out
    # of rover run, rover hil trial --config and rover plan --config, naming neither file nor key.
    with pytest.raises(ConfigError) as caught:
        CanConfig.from_table(parse_toml(text, "rover.toml"))
    assert str(caught.value) == "rover.toml: channel: must not be empty (e.g. 'can0', 'vcan0', 'rover0')"


def test_open_bus_wraps_python_can_errors():
    # This machine has no SocketCAN at all; elsewhere the interface name does not exist. Either way:
    with pytest.raises(BridgeSetupError, match="socketcan:no-such-can9"):
        open_bus(CanConfig(interface="socketcan", channel="no-such-can9"))


@pytest.mark.parametrize("seed", range(3))
def test_preformatted_frame_record_is_the_json_encoders_bytes(seed):
    rng = random.Random(seed)
    for _ in range(500):
        extended = rng.random() < 0.8
        dlc = rng.randrange(9)
        msg = can.Message(
            arbitration_id=rng.randrange(1 << (29 if extended else 11)),
            is_extended_id=extended,
            is_error_frame=rng.random() < 0.1,  # marked "error" in both
            data=rng.randbytes(dlc),
            dlc=dlc,
        )
        t_ns = rng.choice([0, rng.randrange(10**15)])
        direction = rng.choice(["rx", "tx"])
        assert _frame_json(t_ns, direction, msg) == encode_message(_frame_record(t_ns, direction, msg))


@pytest.mark.parametrize("seed", range(3))
def test_frame_records_from_kept_parts_equal_the_formatted_ones(seed):
    """The link's cached formatting (shared timestamps, (direction, id, format, length) text kept) gives the
    record and bytes of _frame_record / _frame_json, for repeated and new kinds, past the cache's bound."""
    rng = random.Random(seed)
    records = _FrameRecords()
    t_ns = 0
    ids = [rng.randrange(1 << 29) for _ in range(8)]
    for _ in range(3 * _MAX_CACHED_FRAME_KINDS):
        if rng.random() < 0.2:
            t_ns = rng.choice([t_ns + 1, t_ns + rng.randrange(10**9), rng.randrange(10**15)])
        extended = rng.random() < 0.8
        dlc = rng.randrange(9)
        arbitration_id = (
            rng.choice(ids) if rng.random() < 0.5 else rng.randrange(1 << (29 if extended else 11))
        )
        msg = can.Message(
            arbitration_id=arbitration_id, is_extended_id=extended, data=rng.randbytes(dlc), dlc=dlc
        )
        direction = rng.choice(["rx", "tx"])
        record, data = records.format(t_ns, direction, msg)
        assert record == _frame_record(t_ns, direction, msg)
        assert data == _frame_json(t_ns, direction, msg) == encode_message(record)
        assert records.json(t_ns, direction, msg) == data


def test_an_encoding_sink_gets_the_same_frame_records(buses):
    class BytesSink(MemorySink):
        def __init__(self):
            super().__init__()
            self.data = []

        def publish_encoded(self, topic, log_time_ns, message, data):
            self.data.append((topic, data))
            self.publish(topic, log_time_ns, message)

    sink = BytesSink()
    link = CanLink(buses[0], make_codec(), SimClock(), sink)
    link.send_wheel_speeds([0.5] * 6)
    frames = [(t, m) for t, _, m in sink.records if t == CAN_FRAMES]
    assert len(frames) == 6
    assert [d for t, d in sink.data if t == CAN_FRAMES] == [encode_message(m) for _, m in frames]


class BytesOnly(MemorySink):
    """A sink that takes frame records as their bytes alone, as the recorder and Zenoh do."""

    records_bytes_only = True

    def __init__(self):
        super().__init__()
        self.data = []
        self.batches = []

    def publish_bytes(self, topic, log_time_ns, data):
        self.data.append((topic, log_time_ns, data))

    def publish_bytes_many(self, topic, log_time_ns, datas):
        self.batches.append((topic, log_time_ns, len(datas)))
        self.data.extend((topic, log_time_ns, data) for data in datas)


class Encoded(MemorySink):
    """A sink that takes each record with its bytes (an EncodedSink), as a fan-out to both does."""

    def __init__(self):
        super().__init__()
        self.data = []

    def publish_encoded(self, topic, log_time_ns, message, data):
        self.data.append((topic, log_time_ns, data))
        self.publish(topic, log_time_ns, message)


def test_a_bytes_only_sink_gets_the_frames_bytes_and_no_dicts(buses):
    """A sink recording bytes alone (the recorder, Zenoh) gets the same frame bytes, both directions, that
    the JSON encoder gives for the records a plain sink gets; everything else still comes as messages."""
    ours, theirs = buses
    bytes_only, plain = BytesOnly(), MemorySink()
    codec = make_codec()
    for sink in (bytes_only, plain):
        clock = SimClock(2_000_000_000)
        link = CanLink(ours, codec, clock, sink)
        link.send_wheel_speeds([0.5, 0.5, 0.5, -0.25, -0.25, 0.0])
        clock.advance(1_000_000)
        theirs.send(codec.encode("STATUS", 2, erpm=1200.0, current=3.5, duty=0.25))
        theirs.send(ext((9 << 8) | 42, bytes(8)))  # unknown controller: rejected, still recorded as rx
        link.poll()
        while theirs.recv(timeout=0) is not None:
            pass
    expected = [(CAN_FRAMES, t, encode_message(m)) for topic, t, m in plain.records if topic == CAN_FRAMES]
    assert len(expected) == 8 and {t for _, t, _ in expected} == {2_000_000_000, 2_001_000_000}
    assert bytes_only.data == expected
    # One call per command round and per poll: six SET_RPM, then the poll's two frames (the rejected one's
    # record included: a rejection sends the frames so far on, ahead of its warning on the log topic).
    assert bytes_only.batches == [(CAN_FRAMES, 2_000_000_000, 6), (CAN_FRAMES, 2_001_000_000, 2)]
    assert not bytes_only.on(CAN_FRAMES)
    assert bytes_only.on(WHEELS_STATUS)[0]["wheels"][1]["erpm"] == 1200.0


def test_error_frames_are_recorded_as_received_marked_error_in_their_place(buses):
    """The controller's error frames go on can/frames among the poll's frames, as received and marked
    "error" (a replay delivers them again: hil.replay), the same bytes whatever the sink; counted as bus
    errors, neither rx nor bus load."""
    ours, theirs = buses
    codec = make_codec()
    busoff = can.Message(
        arbitration_id=CAN_ERR_BUSOFF, is_error_frame=True, is_extended_id=False, data=bytes(8)
    )
    sinks = {"plain": MemorySink(), "encoded": Encoded(), "bytes": BytesOnly()}
    for sink in sinks.values():
        link = CanLink(ours, codec, SimClock(3_000_000_000), sink)
        theirs.send(codec.encode("STATUS", 1, erpm=100.0, current=1.0, duty=0.1))
        theirs.send(busoff)
        theirs.send(codec.encode("STATUS", 2, erpm=200.0, current=1.0, duty=0.1))
        assert link.poll() == 3
        assert (link.counters.rx, link.counters.bus_errors, link.state.value) == (2, 1, "recovering")
        assert link.bits_total == 2 * frame_bits(True, 8)  # the two status frames' bits: none for the error
    records = sinks["plain"].on(CAN_FRAMES)
    assert [(r["id"], r.get("error")) for r in records] == [
        (0x901, None),
        (CAN_ERR_BUSOFF, True),
        (0x902, None),
    ]
    assert records[1] == {
        "timestamp": {"sec": 3, "nsec": 0},
        "direction": "rx",
        "id": CAN_ERR_BUSOFF,
        "extended": False,
        "dlc": 8,
        "data": "00" * 8,
        "error": True,
    }
    expected = [encode_message(r) for r in records]
    assert [d for topic, _, d in sinks["encoded"].data if topic == CAN_FRAMES] == expected
    assert [d for _, _, d in sinks["bytes"].data] == expected
    assert expected[1].endswith(b',"error":true}')
    # Each record goes before the change of state it brought: the error frame's before the bus-off, the
    # next status frame's before the recovery.
    kinds = [t if t == CAN_FRAMES else m["kind"] for t, _, m in sinks["plain"].records if t != WHEELS_STATUS]
    assert kinds == [CAN_FRAMES, CAN_FRAMES, "can_bus_off", CAN_FRAMES, "can_recovering"]


def test_status_read_by_field_decoders_gives_the_readings_decode_gives(buses, monkeypatch):
    """The link reads its status frames with field decoders; a codec without packers (cantools for
    everything) has none, so its link takes every frame through decode: both keep the same readings."""
    fast_codec = make_codec()
    monkeypatch.setattr("firmware_bridge.vesc.FramePacker.for_message", lambda message: None)
    slow_codec = make_codec()
    assert fast_codec.field_decoders("STATUS", ("erpm",)) and not slow_codec.field_decoders(
        "STATUS", ("erpm",)
    )
    ours, theirs = buses
    readings = []
    for codec in (fast_codec, slow_codec):
        rng = random.Random(11)  # the same frames for both
        clock = SimClock()
        link = CanLink(ours, codec, clock, MemorySink())
        for _ in range(40):
            clock.advance(20_000_000)
            for cid in range(1, 7):
                for kind, length in (("STATUS", 8), ("STATUS_4", 8), ("STATUS_5", 8)):
                    frame_id = fast_codec.encoder(kind, cid).message.frame_id
                    theirs.send(ext(frame_id, bytes(rng.randrange(256) for _ in range(length))))
            link.poll()
        readings.append([dataclasses.asdict(r) for r in link.readings()])
        assert link.counters.rx == 40 * 18 and link.counters.rejected == 0
    assert readings[0] == readings[1]
    assert any(r["erpm"] != 0.0 and r["input_voltage_v"] != 0.0 for r in readings[0])


def test_a_safety_event_in_a_poll_is_recorded_after_the_frames_before_it(buses):
    """Frames go to a bytes-only sink a poll at a time, but anything else the link publishes during the
    poll (here: a silent controller reporting again) comes after the frames received before it and
    before those after it, as when each frame was published on its own."""

    class Ordered(MemorySink):
        records_bytes_only = True

        def publish_bytes(self, topic, log_time_ns, data):
            self.records.append((topic, log_time_ns, data))

        def publish_bytes_many(self, topic, log_time_ns, datas):
            self.records.extend((topic, log_time_ns, data) for data in datas)

    ours, theirs = buses
    clock, sink = SimClock(), Ordered()
    codec = make_codec()
    link = CanLink(ours, codec, clock, sink)
    clock.advance(1_000_000_000)
    link.poll()  # a second without status: every controller silent
    assert not any(link.controllers_alive().values())
    del sink.records[:]
    for cid in (1, 2):
        theirs.send(codec.encode("STATUS", cid, erpm=100.0 * cid, current=0.0, duty=0.0))
    link.poll()
    topics = [topic for topic, _, _ in sink.records]
    assert topics[:4] == [CAN_FRAMES, SAFETY_EVENTS, CAN_FRAMES, SAFETY_EVENTS]
    assert [m["kind"] for m in sink.on(SAFETY_EVENTS)] == ["can_controller_alive"] * 2
    assert b'"id":2305' in sink.records[0][2] and b'"id":2306' in sink.records[2][2]  # 0x901, 0x902
