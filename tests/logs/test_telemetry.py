"""Zenoh telemetry: settings, the shipped config, and two sessions talking over loopback."""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Iterator

import pytest
import zenoh

from logs.errors import TelemetryError, TelemetrySetupError
from logs.recorder import encode_message
from logs.settings import ConfigError, parse_toml
from logs.telemetry import (
    TelemetrySample,
    ZenohSettings,
    ZenohTelemetry,
    open_session,
    subscribe,
    zenoh_config,
)
from logs.topics import CAN_FRAMES, ESTIMATOR_INNOVATIONS, LOG, NAVIGATOR_STATE, stamp

WAIT_S = 10.0


def _free_loopback_port() -> int:
    # Ask the OS for a free port; the tiny window before zenoh binds it is acceptable in a test.
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_defaults_are_local_and_quiet() -> None:
    settings = ZenohSettings()
    assert not settings.enabled and settings.mode == "peer" and not settings.multicast_scouting
    config = zenoh_config(settings)
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False
    assert json.loads(config.get_json("scouting/gossip/enabled")) is False
    assert json.loads(config.get_json("mode")) == "peer"
    assert json.loads(config.get_json("listen/endpoints")) == ["tcp/127.0.0.1:0"]


def test_settings_from_table_override_the_shipped_config() -> None:
    absent = parse_toml("", "rover.toml").table("zenoh", optional=True)
    assert ZenohSettings.from_table(absent) == ZenohSettings()  # no [zenoh] table: defaults
    text = '[zenoh]\nenabled = true\nmode = "client"\nconnect = ["tcp/127.0.0.1:7447"]\n'
    root = parse_toml(text, "rover.toml")
    settings = ZenohSettings.from_table(root.table("zenoh"))
    assert settings.enabled and settings.connect == ("tcp/127.0.0.1:7447",)
    config = zenoh_config(settings)
    assert json.loads(config.get_json("connect/endpoints")) == ["tcp/127.0.0.1:7447"]
    assert json.loads(config.get_json("mode")) == "client"


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('mode = "router"', "zenoh.mode"),
        ('listen = "tcp/127.0.0.1:0"', "zenoh.listen"),
        ('connect = ["127.0.0.1:7447"]', "zenoh.connect"),
        ('mode = "client"', "zenoh.connect"),
        ("colour = 3", "zenoh.colour"),
    ],
)
def test_bad_settings_name_the_key(text: str, key: str) -> None:
    table = parse_toml(f"[zenoh]\n{text}\n", "rover.toml").table("zenoh")
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        ZenohSettings.from_table(table)


def test_bad_rover_id_is_a_setup_error() -> None:
    with pytest.raises(TelemetrySetupError, match="rover_id"):
        ZenohTelemetry(None, "r/1")  # type: ignore[arg-type]


@pytest.fixture
def sessions() -> Iterator[tuple[zenoh.Session, zenoh.Session]]:
    port = _free_loopback_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    rover = open_session(ZenohSettings(enabled=True, listen=(endpoint,)))
    try:
        station = open_session(ZenohSettings(enabled=True, listen=(), connect=(endpoint,)))
    except BaseException:
        rover.close()
        raise
    try:
        yield rover, station
    finally:
        station.close()
        rover.close()


class _Collector:
    """Collects samples from zenoh's thread; tests wait on its condition, never sleep."""

    def __init__(self) -> None:
        self.samples: list[TelemetrySample] = []
        self._changed = threading.Condition()

    def __call__(self, sample: TelemetrySample) -> None:
        with self._changed:
            self.samples.append(sample)
            self._changed.notify_all()

    def wait_for(self, predicate: object, timeout: float) -> bool:
        with self._changed:
            return self._changed.wait_for(lambda: predicate(self.samples), timeout)  # type: ignore[operator]


def test_loopback_stream_delivers_same_payloads_and_log_times(
    sessions: tuple[zenoh.Session, zenoh.Session],
) -> None:
    rover, station = sessions
    collector = _Collector()
    subscription = subscribe(station, "r1", collector)
    telemetry = ZenohTelemetry(rover, "r1")
    try:
        # Discovery takes a moment: repeat a probe until one arrives (each wait is bounded).
        for attempt in range(int(WAIT_S / 0.05)):
            telemetry.publish(LOG, attempt, {"probe": attempt})
            if collector.wait_for(lambda samples: len(samples) > 0, 0.05):
                break
        else:
            pytest.fail("the station never received a probe over loopback")

        sent = [
            (NAVIGATOR_STATE, 1_000 + i, {"timestamp": stamp(1_000 + i), "mode": "DRIVING", "xte": i / 7})
            for i in range(20)
        ]
        sent.append((NAVIGATOR_STATE, 5_000, {"mode": "ARRIVED", "xte": float("nan")}))
        for topic, t, message in sent:
            telemetry.publish(topic, t, message)
        # Several of one topic and log time in one call, as a fan-out hands over the CAN link's frames.
        batch = [(NAVIGATOR_STATE, 6_000, {"mode": "ARRIVED", "xte": float(i)}) for i in range(3)]
        telemetry.publish_bytes_many(NAVIGATOR_STATE, 6_000, [encode_message(m) for _, _, m in batch])
        sent += batch

        def got_all(samples: list[TelemetrySample]) -> bool:
            return sum(s.topic == NAVIGATOR_STATE for s in samples) == len(sent)

        assert collector.wait_for(got_all, WAIT_S)
        received = [s for s in collector.samples if s.topic == NAVIGATOR_STATE]
        assert [(s.topic, s.log_time_ns) for s in received] == [(t, ns) for t, ns, _ in sent]
        for sample, (_, _, message) in zip(received, sent, strict=True):
            assert encode_message(sample.message) == encode_message(message)
        assert received[-4].message["xte"] is None  # NaN travels as null, as in the recording
        assert subscription.rejected == 0
        # Probes sent before zenoh reported the station's subscriber were not put (nobody matched).
        assert telemetry.failures == 0 and telemetry.published >= len(sent) + 1
        assert telemetry.published + telemetry.unheard == len(sent) + attempt + 1
        with pytest.raises(TelemetryError, match="unknown topic"):
            telemetry.publish("no/such/topic", 0, {})
    finally:
        telemetry.close()
        telemetry.close()
        subscription.close()
        subscription.close()
    with pytest.raises(TelemetryError, match="closed"):
        telemetry.publish(LOG, 0, {})


def test_station_rejects_samples_without_log_time(sessions: tuple[zenoh.Session, zenoh.Session]) -> None:
    rover, station = sessions
    collector = _Collector()
    subscription = subscribe(station, "r2", collector)
    rejected = threading.Event()
    try:
        for _ in range(int(WAIT_S / 0.05)):
            rover.put("rover/r2/log", b'{"a": 1}')  # no attachment: a foreign publisher
            rover.put("rover/r2/log", b"not json", attachment=(7).to_bytes(8, "little"))
            if subscription.rejected >= 2:
                rejected.set()
                break
            collector.wait_for(lambda samples: False, 0.05)
        assert rejected.is_set()
        assert collector.samples == []
    finally:
        subscription.close()


def test_station_rejects_and_counts_json_nested_past_any_parsers_depth(
    sessions: tuple[zenoh.Session, zenoh.Session],
) -> None:
    # It raised RecursionError out of zenoh's callback: neither counted nor logged.
    rover, station = sessions
    subscription = subscribe(station, "r3", _Collector())
    try:
        deadline = time.monotonic() + WAIT_S
        while subscription.rejected == 0 and time.monotonic() < deadline:
            rover.put("rover/r3/log", b"[" * 100_000 + b"]" * 100_000, attachment=(8).to_bytes(8, "little"))
            time.sleep(0.05)
        assert subscription.rejected >= 1 and subscription.received == 0
    finally:
        subscription.close()


def test_open_session_reports_unusable_endpoint() -> None:
    with pytest.raises(TelemetrySetupError, match="listen"):
        open_session(ZenohSettings(enabled=True, listen=("tcp/256.1.1.1:0",)))


def test_rates_table_limits_the_live_stream_per_topic() -> None:
    from logs.sink import MemorySink
    from logs.telemetry_station import rate_limited

    table = parse_toml('[zenoh]\n[zenoh.rates]\n"estimator/pose" = 10.0\n', "<test>").table("zenoh")
    settings = ZenohSettings.from_table(table)
    assert settings.rates_hz == (("estimator/pose", 10.0),)
    memory = MemorySink()
    sink = rate_limited(memory, settings.rates_hz)
    for tick in range(50):  # one second at 50 Hz
        sink.publish("estimator/pose", tick * 20_000_000, {"n": tick})
        sink.publish(NAVIGATOR_STATE, tick * 20_000_000, {"n": tick})
    assert len(memory.on("estimator/pose")) == 10
    assert len(memory.on(NAVIGATOR_STATE)) == 50
    assert rate_limited(memory, ()) is memory


def test_live_stream_is_thinned_by_default_and_a_rates_table_replaces_the_default() -> None:
    from logs.sink import MemorySink
    from logs.telemetry_station import rate_limited

    default = ZenohSettings.from_table(parse_toml("[zenoh]\n", "<test>").table("zenoh"))
    assert (
        default.rates_hz == ZenohSettings().rates_hz == ((CAN_FRAMES, 100.0), (ESTIMATOR_INNOVATIONS, 20.0))
    )
    memory = MemorySink()
    sink = rate_limited(memory, default.rates_hz)
    for tick in range(100):  # one second at 100 Hz, six frames a tick at the same log time
        for _ in range(6):
            sink.publish(CAN_FRAMES, tick * 10_000_000, {"tick": tick})
        sink.publish(ESTIMATOR_INNOVATIONS, tick * 10_000_000, {"tick": tick})
        sink.publish(NAVIGATOR_STATE, tick * 10_000_000, {"tick": tick})
    assert len(memory.on(CAN_FRAMES)) == 100 and len(memory.on(ESTIMATOR_INNOVATIONS)) == 20
    assert len(memory.on(NAVIGATOR_STATE)) == 100
    # A table of its own replaces the default whole; an empty one streams everything.
    only_pose = parse_toml('[zenoh.rates]\n"estimator/pose" = 5.0\n', "<test>").table("zenoh")
    assert ZenohSettings.from_table(only_pose).rates_hz == (("estimator/pose", 5.0),)
    everything = ZenohSettings.from_table(parse_toml("[zenoh.rates]\n", "<test>").table("zenoh"))
    assert everything.rates_hz == ()
    assert rate_limited(memory, everything.rates_hz) is memory


def test_rates_for_unknown_topics_are_refused() -> None:
    table = parse_toml('[zenoh.rates]\n"no/such" = 5.0\n', "<test>").table("zenoh")
    with pytest.raises(ConfigError, match="no/such"):
        ZenohSettings.from_table(table)


class _Matching:
    def __init__(self, matching: bool) -> None:
        self.matching = matching


class _PutRecorder:
    """A publisher that keeps what it was given (no network): payload and attachment bytes per put.

    Its matching status (whether a subscriber would receive its puts) starts as ``matching``; ``match``
    changes it and reports the change to the matching listener's handler, as zenoh does."""

    def __init__(self, matching: bool = True) -> None:
        self.puts: list[tuple[bytes, bytes]] = []
        self.matching_status = _Matching(matching)
        self._reported: list[_Matching] = []

    def put(self, payload: bytes, *, attachment: zenoh.ZBytes) -> None:
        self.puts.append((payload, attachment.to_bytes()))

    def declare_matching_listener(self, handler: object) -> _PutRecorder:
        return self

    def try_recv(self) -> _Matching | None:
        return self._reported.pop() if self._reported else None

    def match(self, matching: bool) -> None:
        self.matching_status = _Matching(matching)
        self._reported = [_Matching(matching)]  # a ring of one: the latest change

    def undeclare(self) -> None:
        return None


class _StubSession:
    def __init__(self, matching: bool = True) -> None:
        self.publishers: dict[str, _PutRecorder] = {}
        self.congestion: dict[str, zenoh.CongestionControl] = {}
        self._matching = matching

    def declare_publisher(
        self, key: str, encoding: zenoh.Encoding, congestion_control: zenoh.CongestionControl
    ) -> _PutRecorder:
        self.congestion[key] = congestion_control
        return self.publishers.setdefault(key, _PutRecorder(self._matching))


@pytest.mark.parametrize(
    ("blocking", "expected"), [(False, zenoh.CongestionControl.DROP), (True, zenoh.CongestionControl.BLOCK)]
)
def test_puts_drop_when_congested_unless_asked_to_block(
    blocking: bool, expected: zenoh.CongestionControl
) -> None:
    session = _StubSession()
    telemetry = ZenohTelemetry(session, "r1", block_when_congested=blocking)  # type: ignore[arg-type]
    telemetry.publish_bytes(LOG, 1, b"{}")
    assert session.congestion == {"rover/r1/log": expected}


def test_each_put_carries_its_own_log_time_and_a_bad_one_is_counted() -> None:
    # The attachment is reused while the log time is the same object; an equal value of another object
    # gives the same bytes, and a log time that is no int fails the put (counted), the first one too.
    session = _StubSession()
    telemetry = ZenohTelemetry(session, "r1")  # type: ignore[arg-type]
    telemetry.publish_bytes(LOG, None, b"{}")  # type: ignore[arg-type]
    assert telemetry.failures == 1 and telemetry.published == 0
    first = 2**40 + 1
    same_value = int(str(first))
    for log_time_ns in (first, first, same_value, 7, 7.5, 8):
        telemetry.publish_bytes(LOG, log_time_ns, b'{"a":1}')  # type: ignore[arg-type]
    puts = session.publishers["rover/r1/log"].puts
    assert [int.from_bytes(attachment, "little", signed=True) for _, attachment in puts] == [
        first,
        first,
        first,
        7,
        8,
    ]
    assert telemetry.failures == 2 and telemetry.published == 5
    telemetry.close()
    with pytest.raises(TelemetryError, match="closed"):
        telemetry.publish_bytes(LOG, 9, b"{}")


def test_nothing_is_put_while_no_subscriber_matches_and_everything_once_one_does() -> None:
    session = _StubSession(matching=False)
    telemetry = ZenohTelemetry(session, "r1")  # type: ignore[arg-type]
    telemetry.publish_bytes(LOG, 1, b'{"n":1}')
    telemetry.publish_bytes_many(LOG, 2, [b'{"n":2}', b'{"n":3}'])
    publisher = session.publishers["rover/r1/log"]
    assert publisher.puts == [] and telemetry.unheard == 3 and telemetry.published == 0
    telemetry.publish_bytes(LOG, None, b"{}")  # type: ignore[arg-type]
    assert telemetry.failures == 1  # a bad log time is counted though nobody listens
    publisher.match(True)  # a subscriber came
    telemetry.publish_bytes_many(LOG, 4, [b'{"n":4}', b'{"n":5}'])
    assert [payload for payload, _ in publisher.puts] == [b'{"n":4}', b'{"n":5}']
    assert telemetry.published == 2 and telemetry.unheard == 3
    publisher.match(False)  # and went
    telemetry.publish_bytes(LOG, 6, b'{"n":6}')
    assert len(publisher.puts) == 2 and telemetry.unheard == 4
    # A topic declared while a subscriber matches puts from its first message (the status read then).
    matched = _StubSession(matching=True)
    telemetry = ZenohTelemetry(matched, "r1")  # type: ignore[arg-type]
    telemetry.publish_bytes(NAVIGATOR_STATE, 7, b'{"n":7}')
    assert matched.publishers["rover/r1/navigator/state"].puts[0][0] == b'{"n":7}'
    assert telemetry.published == 1 and telemetry.unheard == 0


def test_a_subscriber_in_the_session_gets_a_topic_once_zenoh_reports_the_match() -> None:
    session = open_session(ZenohSettings(enabled=True))
    try:
        telemetry = ZenohTelemetry(session, "r3")
        telemetry.publish_bytes(LOG, 1, b'{"n":1}')  # nobody subscribed: not put
        assert telemetry.unheard == 1 and telemetry.published == 0
        collector = _Collector()
        subscription = subscribe(session, "r3", collector)
        try:
            # A publisher declared after the subscriber matches from its first message.
            telemetry.publish_bytes(NAVIGATOR_STATE, 2, b'{"n":2}')
            assert telemetry.published == 1
            assert collector.wait_for(lambda samples: len(samples) == 1, WAIT_S)
            # The log publisher, declared before the subscriber, puts once zenoh has reported the match.
            log_messages = 1
            while telemetry.published < 2:
                assert log_messages < WAIT_S / 0.01, "zenoh never reported the subscriber's match"
                collector.wait_for(lambda samples: False, 0.01)
                telemetry.publish_bytes(LOG, 3, b'{"n":3}')
                log_messages += 1
            assert collector.wait_for(lambda samples: len(samples) == 2, WAIT_S)
            assert [s.topic for s in collector.samples] == [NAVIGATOR_STATE, LOG]
            assert telemetry.published + telemetry.unheard == 1 + log_messages
        finally:
            subscription.close()
            telemetry.close()
    finally:
        session.close()
