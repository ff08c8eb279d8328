"""One encoding per message: the encoder reads back as ``json.dumps`` would, and a fanout shares its bytes."""

from __future__ import annotations

import io
import json
import math
import random
from collections.abc import Sequence
from typing import Any

import numpy as np
import orjson
import pytest

from logs.encoding import bytes_only_sink, encode_message
from logs.errors import LogsError, RecordingError, TelemetryError
from logs.recorder import McapRecorder
from logs.sink import FanoutSink, MemorySink, Message
from logs.telemetry_station import RateLimitedSink
from logs.topics import CAN_FRAMES, LOG


def _random_value(rng: random.Random, depth: int = 0) -> Any:
    kind = rng.randrange(7 if depth < 3 else 5)
    if kind == 0:
        return rng.uniform(-1e6, 1e6) * 10 ** rng.randint(-12, 12)
    if kind == 1:
        return rng.randint(-(2**40), 2**40)
    if kind == 2:
        return "".join(rng.choice('ab"\\\n\u00e9\u2603 /') for _ in range(rng.randrange(8)))
    if kind == 3:
        return rng.choice([True, False, None])
    if kind == 4:
        return rng.choice([0.1, -0.0, 1e-300, 5e-324, 1.7976931348623157e308, 25.200000000000003])
    if kind == 5:
        return [_random_value(rng, depth + 1) for _ in range(rng.randrange(5))]
    return {f"k{i}": _random_value(rng, depth + 1) for i in range(rng.randrange(5))}


@pytest.mark.parametrize("seed", range(5))
def test_encoder_reads_back_exactly_what_json_dumps_does(seed: int) -> None:
    # Float text may differ (orjson writes 7e-05 as 0.00007); the numbers read back must not.
    rng = random.Random(seed)
    for _ in range(200):
        message = {"timestamp": {"sec": 1, "nsec": 2}, "value": _random_value(rng)}
        expected = json.dumps(message, separators=(",", ":"), allow_nan=False)
        data = encode_message(message)
        assert json.loads(data) == json.loads(expected)
    assert encode_message({"a": [1, 2.5], "b": {"c": None}}) == b'{"a":[1,2.5],"b":{"c":null}}'


def test_numpy_values_big_integers_and_int_keys_encode_as_json_dumps_would() -> None:
    message: dict[Any, Any] = {
        "array": np.array([[1.0, np.nan], [np.inf, -2.5]]),
        "scalar": np.float32(0.25),
        "count": np.int64(7),
        "flag": np.bool_(True),
        "big": 2**70,
        3: "int key",
    }
    assert json.loads(encode_message(message)) == {
        "array": [[1.0, None], [None, -2.5]],
        "scalar": 0.25,
        "count": 7,
        "flag": True,
        "big": 2**70,
        "3": "int key",
    }


class _Key(str):
    """A str subclass as a dict key: orjson's fast form refuses it, as it refuses an int."""


@pytest.mark.parametrize("seed", range(3))
def test_fast_first_try_writes_the_bytes_of_the_any_key_form(seed: int) -> None:
    # encode_message tries orjson without OPT_NON_STR_KEYS first (faster) and again with it when a key
    # is refused: either way the bytes are those of the one-call any-key form, nested keys included.
    any_key = orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS
    rng = random.Random(seed)
    for index in range(200):
        message: dict[Any, Any] = {"timestamp": {"sec": 1, "nsec": 2}, "value": _random_value(rng)}
        if index % 3 == 1:
            message["nested"] = {7: np.float32(0.5), "list": [{2.5: "float key"}]}
        elif index % 3 == 2:
            message[_Key("sub")] = {None: np.arange(3)}
        assert encode_message(message) == orjson.dumps(message, option=any_key)


def test_encoder_can_be_reused_after_a_failed_message() -> None:
    with pytest.raises(TypeError):
        encode_message({"a": {"b": object()}})
    assert encode_message({"a": {"b": [math.inf, np.float64(1.5)]}}) == b'{"a":{"b":[null,1.5]}}'
    assert encode_message({"a": 1}) == b'{"a":1}'


def test_circular_message_is_a_value_error() -> None:
    message: dict[str, Any] = {}
    message["self"] = message
    with pytest.raises(ValueError, match="circular"):
        encode_message(message)


class _CountingEncodedSink(MemorySink):
    """A sink that takes encoded bytes, keeping them next to the message."""

    def __init__(self) -> None:
        super().__init__()
        self.data: list[bytes] = []

    def publish_encoded(self, topic: str, log_time_ns: int, message: Message, data: bytes) -> None:
        self.data.append(data)
        self.publish(topic, log_time_ns, message)


def test_fanout_encodes_once_and_shares_the_bytes(monkeypatch: pytest.MonkeyPatch) -> None:
    import logs.sink

    calls = []
    dumps = orjson.dumps

    def counting(message: Message, **options: Any) -> bytes:
        calls.append(message)
        return dumps(message, **options)

    # The fan-out makes encode_message's orjson step inline: count the encodings there.
    monkeypatch.setattr(logs.sink.orjson, "dumps", counting)
    first, second, plain = _CountingEncodedSink(), _CountingEncodedSink(), MemorySink()
    limited = RateLimitedSink(second, {CAN_FRAMES: 10.0})
    fanout = FanoutSink([first, limited, plain])
    for tick in range(10):  # 100 Hz for 0.1 s: the rate limit passes the first only
        fanout.publish(CAN_FRAMES, tick * 10_000_000, {"i": tick, "x": 0.5})
    assert len(calls) == 10
    assert first.data == [encode_message({"i": tick, "x": 0.5}) for tick in range(10)]
    assert second.data == first.data[:1] and limited.dropped == 9
    assert [m for _, _, m in plain.records] == [{"i": tick, "x": 0.5} for tick in range(10)]


def test_fanout_lets_each_sink_report_a_message_it_cannot_encode() -> None:
    recorder = McapRecorder(io.BytesIO())
    memory = MemorySink()
    fanout = FanoutSink([memory, recorder])
    with pytest.raises(RecordingError, match="cannot be encoded"):
        fanout.publish(LOG, 0, {"bad": object()})
    assert len(memory.records) == 1
    recorder.close()


def test_fanout_shares_the_bytes_of_what_only_the_standard_library_encodes() -> None:
    # orjson refuses an integer beyond 64 bits: the fan-out's inline orjson step hands the message to
    # encode_message, whose fallback bytes every sink gets.
    first, second = _CountingEncodedSink(), _CountingEncodedSink()
    message = {"big": 2**70, "x": math.nan}
    FanoutSink([first, second]).publish(LOG, 0, message)
    assert first.data == second.data == [b'{"big":1180591620717411303424,"x":null}']
    assert first.data == [encode_message(message)]


class _BytesOnlySink:
    """A sink that records bytes alone (``BytesSink``), keeping them in order."""

    records_bytes_only = True

    def __init__(self) -> None:
        self.data: list[tuple[str, int, bytes]] = []

    def publish(self, topic: str, log_time_ns: int, message: Message) -> None:
        self.publish_bytes(topic, log_time_ns, encode_message(message))

    def publish_bytes(self, topic: str, log_time_ns: int, data: bytes) -> None:
        self.data.append((topic, log_time_ns, data))

    def publish_bytes_many(self, topic: str, log_time_ns: int, datas: Sequence[bytes]) -> None:
        self.data.extend((topic, log_time_ns, data) for data in datas)


def test_a_fanout_of_bytes_only_sinks_passes_bytes_alone_and_thins_as_for_messages() -> None:
    first, second = _BytesOnlySink(), _BytesOnlySink()
    limited = RateLimitedSink(second, {CAN_FRAMES: 10.0})
    fanout = FanoutSink([first, limited])
    assert bytes_only_sink(fanout) is fanout and bytes_only_sink(limited) is limited
    for tick in range(10):  # 100 Hz for 0.1 s, half as messages, half as bytes: the limit passes the first
        message = {"i": tick, "x": 0.5}
        if tick % 2:
            fanout.publish_bytes(CAN_FRAMES, tick * 10_000_000, encode_message(message))
        else:
            fanout.publish(CAN_FRAMES, tick * 10_000_000, message)
    expected = [(CAN_FRAMES, tick * 10_000_000, encode_message({"i": tick, "x": 0.5})) for tick in range(10)]
    assert first.data == expected
    assert second.data == expected[:1] and limited.dropped == 9


def test_bytes_alone_are_refused_where_a_sink_needs_the_message() -> None:
    memory = MemorySink()
    fanout = FanoutSink([_BytesOnlySink(), memory])
    limited = RateLimitedSink(memory, {CAN_FRAMES: 10.0})
    assert bytes_only_sink(fanout) is None and bytes_only_sink(limited) is None
    assert bytes_only_sink(memory) is None
    with pytest.raises(LogsError, match="needs each message itself"):
        fanout.publish_bytes(CAN_FRAMES, 0, b"{}")
    with pytest.raises(TelemetryError, match="needs each message itself"):
        limited.publish_bytes(CAN_FRAMES, 0, b"{}")
    assert memory.records == []


def test_the_recorder_records_bytes_alone_as_it_records_messages() -> None:
    from mcap.reader import make_reader

    message = {
        "timestamp": {"sec": 1, "nsec": 2},
        "level": 2,
        "message": "hi",
        "name": "t",
        "file": "",
        "line": 0,
    }
    streams = []
    for as_bytes in (False, True):
        stream = io.BytesIO()
        recorder = McapRecorder(stream)
        assert bytes_only_sink(recorder) is recorder
        if as_bytes:
            recorder.publish_bytes(LOG, 5, encode_message(message))
        else:
            recorder.publish(LOG, 5, message)
        with pytest.raises(RecordingError, match="non-negative"):
            recorder.publish_bytes(LOG, -1, b"{}")
        recorder.close()
        with pytest.raises(RecordingError, match="closed"):
            recorder.publish_bytes(LOG, 6, b"{}")
        stream.seek(0)
        streams.append([(c.topic, m.log_time, m.data) for _, c, m in make_reader(stream).iter_messages()])
    assert streams[0] == streams[1] == [(LOG, 5, encode_message(message))]


# 2e9 Hz: a period that rounds to 0 ns, so nothing is thinned.
@pytest.mark.parametrize("rate_hz", [10.0, 2e9])
def test_a_batch_is_recorded_and_thinned_as_its_messages_one_by_one(rate_hz: float) -> None:
    """``publish_bytes_many`` through a fan-out of the recorder and a rate limiter gives the same MCAP file
    (records, chunks, summary) and the same live stream and drop count as ``publish_bytes`` per message."""
    rng = random.Random(3)
    batches = []
    t_ns = 0
    for _ in range(60):
        t_ns += rng.choice([0, 1, 20_000_000, 110_000_000, 400_000_000])
        topic = rng.choice([CAN_FRAMES, CAN_FRAMES, LOG])
        datas = [encode_message({"i": rng.randrange(1000)}) for _ in range(rng.choice([0, 1, 6, 18]))]
        batches.append((topic, t_ns, datas))
    outputs = []
    for batched in (False, True):
        stream, live = io.BytesIO(), _BytesOnlySink()
        recorder = McapRecorder(stream, chunk_duration_ns=300_000_000)
        limited = RateLimitedSink(live, {CAN_FRAMES: rate_hz})
        fanout = FanoutSink([recorder, limited])
        for topic, t_ns, datas in batches:
            if batched:
                fanout.publish_bytes_many(topic, t_ns, datas)
            else:
                for data in datas:
                    fanout.publish_bytes(topic, t_ns, data)
        recorder.close()
        outputs.append((stream.getvalue(), recorder.message_count, live.data, limited.dropped))
    assert outputs[0] == outputs[1]
    assert outputs[0][1] == sum(len(datas) for _, _, datas in batches)
    assert (outputs[0][3] > 0) == (rate_hz == 10.0)


def test_a_batch_is_refused_as_its_messages_would_be() -> None:
    recorder = McapRecorder(io.BytesIO())
    with pytest.raises(RecordingError, match="non-negative"):
        recorder.publish_bytes_many(CAN_FRAMES, -1, [b"{}"])
    with pytest.raises(RecordingError, match="unknown topic"):
        recorder.publish_bytes_many("no/such/topic", 0, [b"{}"])
    recorder.publish_bytes_many(CAN_FRAMES, 0, [b"{}", b"{}"])
    recorder.close()
    assert recorder.message_count == 2
    with pytest.raises(RecordingError, match="closed"):
        recorder.publish_bytes_many(CAN_FRAMES, 1, [b"{}"])
    with pytest.raises(LogsError, match="needs each message itself"):
        FanoutSink([_BytesOnlySink(), MemorySink()]).publish_bytes_many(CAN_FRAMES, 0, [b"{}"])
    with pytest.raises(TelemetryError, match="needs each message itself"):
        RateLimitedSink(MemorySink(), {CAN_FRAMES: 10.0}).publish_bytes_many(CAN_FRAMES, 0, [b"{}"])
