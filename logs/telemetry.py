"""Live telemetry over Zenoh: the same topics and JSON payloads as the MCAP recording.

Key space: ``rover/<rover_id>/<topic>`` (e.g. ``rover/r1/estimator/pose``). The payload is exactly the
bytes the recorder writes for that message (compact JSON, NaN as null, encoding ``application/json``), so a
ground station decodes both the same way. The log time travels in the sample's *attachment*: 8 bytes,
little-endian signed int64 nanoseconds from the publisher's clock. It is not folded into the payload, so
payloads stay byte-identical to the recording.

The default Zenoh config ships as ``logs/zenoh_default.json5`` (peer mode, loopback listen endpoint,
multicast scouting and gossip off); ``ZenohSettings`` from the rover config override its endpoints.
Telemetry never stops the rover: a failed put is counted and logged, not raised.
"""

from __future__ import annotations

import contextlib
import json
import logging
import re
import struct
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib import resources
from typing import Any

import zenoh

from logs.encoding import encode_message
from logs.errors import TelemetryError, TelemetrySetupError
from logs.json_text import loads_json
from logs.settings import Table, did_you_mean
from logs.sink import Message
from logs.topics import CAN_FRAMES, CAN_STATS, ESTIMATOR_INNOVATIONS, TOPICS

logger = logging.getLogger(__name__)

DEFAULT_CONFIG_RESOURCE = "zenoh_default.json5"
KEY_PREFIX = "rover"
_LOG_TIME = struct.Struct("<q")
_MODES = ("peer", "client")
_FORBIDDEN_IN_ID = set("/*$?#")
_MAX_WARNINGS = 10
_ZENOH_MSG = re.compile(r'msg: "(.*?)"(?:, location|\s*\})')
_RUST_LOCATION = re.compile(r" at \S+\.rs:\d+\.?")


# The live stream's default thinning: the two topics that outnumber all others together. CAN frames come
# at ~720/s (every command and status frame) and the estimator's innovations at ~115/s; a ground station
# plots them, it does not need each one (the MCAP keeps them all). In (topic, messages/s) pairs, sorted.
DEFAULT_RATES_HZ: tuple[tuple[str, float], ...] = ((CAN_FRAMES, 100.0), (ESTIMATOR_INNOVATIONS, 20.0))


@dataclass(frozen=True)
class ZenohSettings:
    """The ``[zenoh]`` table of the rover config. ``rover_id`` is the caller's (it names the key space)."""

    enabled: bool = False
    mode: str = "peer"
    listen: tuple[str, ...] = ("tcp/127.0.0.1:0",)
    connect: tuple[str, ...] = ()
    multicast_scouting: bool = False
    # Zenoh config paths -> values, written last: authentication, TLS, access control (docs/telemetry.md),
    # e.g. {"transport/auth/usrpwd/user": "station"}. A tuple of pairs so the settings stay hashable.
    overrides: tuple[tuple[str, Any], ...] = ()
    # Topic -> maximum messages per second on the live stream (``[zenoh.rates]``); unlisted topics are
    # sent at full rate. The MCAP recording always keeps everything. A ``[zenoh.rates]`` table replaces
    # the default whole: an empty one streams every topic at full rate.
    rates_hz: tuple[tuple[str, float], ...] = DEFAULT_RATES_HZ

    @classmethod
    def from_table(cls, table: Table, *, finish: bool = True) -> ZenohSettings:
        """Read and check the table; ``finish=False`` when the caller keeps its own keys in it."""
        defaults = cls()
        settings = cls(
            enabled=table.flag("enabled", defaults.enabled),
            mode=table.text("mode", defaults.mode, choices=_MODES),
            listen=_endpoints(table, "listen", defaults.listen),
            connect=_endpoints(table, "connect", defaults.connect),
            multicast_scouting=table.flag("multicast_scouting", defaults.multicast_scouting),
            overrides=_overrides(table),
            rates_hz=_rates(table),
        )
        if settings.mode == "client" and not settings.connect:
            raise table.error("connect", "client mode needs at least one endpoint to connect to (a router)")
        if finish:
            table.finish()
        return settings


def _overrides(table: Table) -> tuple[tuple[str, Any], ...]:
    if not table.has("overrides"):
        return ()
    value = table.raw("overrides")
    if not isinstance(value, dict):
        raise table.error(
            "overrides", "expected a table of zenoh config paths, e.g. 'transport/auth/usrpwd/user'"
        )
    return tuple(sorted(value.items()))


# Topics the live stream must carry whole: the station's figures depend on every message of them.
NEVER_THINNED = frozenset({CAN_STATS})


def _rates(table: Table) -> tuple[tuple[str, float], ...]:
    if not table.has("rates"):
        return DEFAULT_RATES_HZ
    rates = table.table("rates")
    result = []
    for topic in sorted(rates.keys()):
        if topic not in TOPICS:
            known = sorted(TOPICS)
            raise rates.error(
                topic, f"unknown topic ({did_you_mean(topic, known)}known topics: {', '.join(known)})"
            )
        if topic in NEVER_THINNED:
            # Refused on load, not when the stream opens: the rover must not get as far as its links.
            raise rates.error(topic, "is never thinned (the ground station's bus load comes from it; ~1/s)")
        result.append((topic, rates.number(topic, lo=0.01, hi=10_000.0)))
    rates.finish()
    return tuple(result)


def _endpoints(table: Table, key: str, default: tuple[str, ...]) -> tuple[str, ...]:
    value = table.raw(key, list(default))
    if not isinstance(value, list) or not all(isinstance(item, str) for item in value):
        raise table.error(key, f"expected a list of endpoints like ['tcp/127.0.0.1:7447'], got {value!r}")
    for item in value:
        problem = endpoint_problem(item)
        if problem is not None:
            raise table.error(key, problem)
    return tuple(value)


def endpoint_problem(endpoint: str) -> str | None:
    """Why ``endpoint`` is not a Zenoh endpoint, or None; zenoh checks the rest when the config is built."""
    protocol, slash, address = endpoint.partition("/")
    if not protocol or not slash or not address:
        return f"endpoint {endpoint!r} is not '<protocol>/<address>' ('tcp/127.0.0.1:7447')"
    return None


def zenoh_config(settings: ZenohSettings) -> zenoh.Config:
    """The shipped default config with the settings' mode, endpoints and scouting choice written over it."""
    try:
        text = resources.files("logs").joinpath(DEFAULT_CONFIG_RESOURCE).read_text(encoding="utf-8")
        config = zenoh.Config.from_json5(text)
    except (OSError, zenoh.ZError) as err:
        raise TelemetrySetupError(
            f"cannot load the shipped Zenoh config {DEFAULT_CONFIG_RESOURCE}: {err}"
        ) from err
    # Each setting is written on its own so a refusal names the value the user gave (an endpoint typed on
    # the command line or in the rover config), not the shipped file.
    written: list[tuple[str, str, object]] = [
        ("mode", "mode", settings.mode),
        ("listen/endpoints", "listen endpoints", list(settings.listen)),
        ("connect/endpoints", "connect endpoints", list(settings.connect)),
        ("scouting/multicast/enabled", "multicast_scouting", settings.multicast_scouting),
    ]
    written += [(path, f"[zenoh.overrides] {path!r} =", value) for path, value in settings.overrides]
    for path, what, value in written:
        try:
            config.insert_json5(path, json.dumps(value))
        except (zenoh.ZError, TypeError) as err:
            raise TelemetrySetupError(f"{what} {value!r} is refused by zenoh: {_zenoh_reason(err)}") from err
    return config


def _zenoh_reason(err: Exception) -> str:
    """zenoh's message without its Rust wrapping (``Json5Err(Message { msg: ...``) and source locations."""
    text = str(err)
    inner = _ZENOH_MSG.search(text)
    reason = _RUST_LOCATION.sub("", inner.group(1) if inner else text).strip()
    return reason or type(err).__name__


def open_session(settings: ZenohSettings) -> zenoh.Session:
    """Open a Zenoh session as configured; the caller closes it (``session.close()``)."""
    config = zenoh_config(settings)
    try:
        return zenoh.open(config)
    except zenoh.ZError as err:
        raise TelemetrySetupError(
            f"cannot open a Zenoh session (listen={list(settings.listen)}, "
            f"connect={list(settings.connect)}): {err}; check the [zenoh] endpoints in the rover config"
        ) from err


def key_prefix(rover_id: str) -> str:
    if not rover_id or _FORBIDDEN_IN_ID & set(rover_id):
        raise TelemetrySetupError(
            f"rover_id {rover_id!r} cannot name a Zenoh key: use a non-empty id without / * $ ? #"
        )
    return f"{KEY_PREFIX}/{rover_id}"


class _TopicStream:
    """One topic's publisher and whether some subscriber's key covers it (zenoh's *matching status*).

    A put that no subscriber matches goes nowhere, yet costs about as much as one that is delivered
    (~0.7 us: the payload copied into zenoh, the routing looked up); a lockstep trial streamed to nobody
    (``rover bench hil``) made ~20,000 of them. So the stream puts only while ``heard``. The status is read
    once at declaration; zenoh reports each later change to a matching listener whose handler keeps the
    latest one (a ring of one), which ``take_change`` takes without waiting (~0.1 us) before each message.
    A handler, not a Python callback: zenoh runs each callback on a thread of its own that holds up the
    process's exit until the session closes.
    """

    def __init__(self, publisher: zenoh.Publisher) -> None:
        self.publisher = publisher
        self.listener = publisher.declare_matching_listener(zenoh.handlers.RingChannel(1))
        # A change reported before the status is read is the same status or an older one, and a newer
        # change is taken later: the latest report always ends in ``heard``.
        self.take_change = self.listener.try_recv
        self.heard = _matching(publisher.matching_status)

    def undeclare(self) -> None:
        self.listener.undeclare()
        self.publisher.undeclare()


def _matching(status: object) -> bool:
    # eclipse-zenoh 1.x gives a MatchingStatus, though its type stub says bool for a publisher's
    # matching_status: either is read.
    return bool(getattr(status, "matching", status))


class ZenohTelemetry:
    """``MessageSink`` publishing each message to ``rover/<rover_id>/<topic>``.

    The session is the caller's: ``close()`` undeclares our publishers, not the session. One publisher per
    topic, declared on first use. A message that no subscriber would receive (zenoh's matching status:
    no subscriber's key covers the topic) is not put at all, only counted (``unheard``); a subscriber gets
    every message from the moment zenoh reports the match (milliseconds after it subscribes).

    Congestion: by default a put that finds the link's queue full is dropped (zenoh's ``DROP``), so a slow
    or stalled subscriber can never hold up the rover's control loop. ``block_when_congested`` makes puts
    wait for room instead (``BLOCK``): nothing is lost, at the cost of the publisher's pace. That suits a
    lockstep trial streamed to a consumer that must see every message (it runs many times real time and
    can outpace the link), never a real-time loop.
    """

    def __init__(self, session: zenoh.Session, rover_id: str, *, block_when_congested: bool = False) -> None:
        self._session = session
        self._congestion = (
            zenoh.CongestionControl.BLOCK if block_when_congested else zenoh.CongestionControl.DROP
        )
        self._prefix = key_prefix(rover_id)
        self._streams: dict[str, _TopicStream] = {}
        self._closed = False
        self.published = 0
        self.unheard = 0  # messages not put: no subscriber matched their topic
        self.failures = 0
        # The attachment of the last put and its log time: the messages of one tick share their log time
        # (~5 puts per attachment in a lockstep trial), and zenoh takes a ZBytes it is given as it is,
        # where bytes are converted on every put (~0.15 us of a ~0.65 us put).
        # Before the first put: an object of our own, so the first log time, whatever it is, is packed
        # (None or a float: the put fails, counted and logged, as every later bad one does).
        self._attachment_ns: object = object()
        self._attachment = zenoh.ZBytes(b"")

    def publish(self, topic: str, log_time_ns: int, message: Message) -> None:
        try:
            payload = encode_message(message)
        except (TypeError, ValueError) as err:
            raise TelemetryError(f"{topic} at {log_time_ns} ns: message cannot be encoded: {err}") from err
        self.publish_bytes(topic, log_time_ns, payload)

    def publish_encoded(self, topic: str, log_time_ns: int, message: Message, data: bytes) -> None:
        """Put ``data`` (``encode_message(message)``, shared with the recorder by a ``FanoutSink``)."""
        self.publish_bytes(topic, log_time_ns, data)

    # BytesSink (logs.encoding): the payload is the bytes; the message itself is never looked at.
    records_bytes_only = True

    def publish_bytes(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """Put ``data``, a message's JSON bytes (when some subscriber would receive it)."""
        # A closed stream has no publishers (close), so a publisher found is an open stream's: the message
        # that finds none goes to _declare, which refuses on a closed stream.
        stream = self._streams.get(topic)
        if stream is None:
            stream = self._declare(topic)
            if stream is None:
                return
        try:
            # Identity, not equality: the messages of one tick pass the clock's very int object, and a
            # different object of the same value only builds the same attachment again. Built whether or
            # not the message is put: a log time that is no int is counted as a failure either way.
            if log_time_ns is not self._attachment_ns:
                self._attachment = zenoh.ZBytes(_LOG_TIME.pack(log_time_ns))
                self._attachment_ns = log_time_ns
            change = stream.take_change()
            if change is not None:  # a subscriber came or went
                stream.heard = _matching(change)
            if not stream.heard:
                self.unheard += 1
                return
            stream.publisher.put(data, attachment=self._attachment)
        except (zenoh.ZError, struct.error) as err:
            self._failed("put on %s failed: %s", topic, err)
            return
        self.published += 1

    def publish_bytes_many(self, topic: str, log_time_ns: int, datas: Sequence[bytes]) -> None:
        """Put each of ``datas`` in turn (a rate limiter in front lets at most one of them through)."""
        for data in datas:
            self.publish_bytes(topic, log_time_ns, data)

    def _declare(self, topic: str) -> _TopicStream | None:
        if self._closed:
            raise TelemetryError(f"telemetry {self._prefix} is closed; cannot publish {topic!r}")
        if topic not in TOPICS:
            known = ", ".join(sorted(TOPICS))
            raise TelemetryError(f"cannot publish unknown topic {topic!r}; known topics: {known}")
        try:
            publisher = self._session.declare_publisher(
                f"{self._prefix}/{topic}",
                encoding=zenoh.Encoding.APPLICATION_JSON,
                congestion_control=self._congestion,
            )
        except zenoh.ZError as err:
            self._failed("cannot declare a publisher for %s: %s", topic, err)
            return None
        try:
            stream = _TopicStream(publisher)
        except zenoh.ZError as err:
            # The publisher is ours alone: undeclared here, not left declared for the session's life.
            with contextlib.suppress(zenoh.ZError):
                publisher.undeclare()
            self._failed("cannot follow who subscribes to %s: %s", topic, err)
            return None
        self._streams[topic] = stream
        return stream

    def _failed(self, fmt: str, *args: object) -> None:
        self.failures += 1
        if self.failures <= _MAX_WARNINGS:
            logger.warning(fmt, *args)

    def close(self) -> None:
        """Undeclare the publishers. Safe to call twice."""
        if self._closed:
            return
        self._closed = True
        for stream in self._streams.values():
            try:
                stream.undeclare()
            except zenoh.ZError as err:
                logger.debug("undeclaring %s failed: %s", stream.publisher.key_expr, err)
        self._streams.clear()


@dataclass(frozen=True)
class TelemetrySample:
    topic: str
    log_time_ns: int
    message: dict[str, Any]


class TelemetrySubscription:
    """A subscriber on ``rover/<rover_id>/<topic>`` (every topic: ``**``); samples that do not decode are
    counted, not raised."""

    def __init__(
        self,
        session: zenoh.Session,
        rover_id: str,
        callback: Callable[[TelemetrySample], None],
        topic: str = "**",
    ) -> None:
        self._prefix = key_prefix(rover_id) + "/"
        self._callback = callback
        self._lock = threading.Lock()  # zenoh calls back on its own threads
        self.received = 0
        self.rejected = 0
        self._closed = False
        key = self._prefix + topic
        try:
            self._subscriber = session.declare_subscriber(key, self._on_sample)
        except zenoh.ZError as err:
            raise TelemetrySetupError(f"cannot subscribe to {key}: {err}") from err

    def _on_sample(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        try:
            decoded = self._decode(key, sample)
        except (ValueError, UnicodeDecodeError, struct.error) as err:
            with self._lock:
                self.rejected += 1
                rejected = self.rejected
            if rejected <= _MAX_WARNINGS:
                logger.warning("telemetry sample on %s rejected: %s", key, err)
            return
        with self._lock:
            self.received += 1
        try:
            self._callback(decoded)
        except Exception:  # a broken callback must not kill zenoh's delivery thread
            logger.exception("telemetry callback failed on %s", key)

    def _decode(self, key: str, sample: zenoh.Sample) -> TelemetrySample:
        if not key.startswith(self._prefix):
            raise ValueError(f"key outside {self._prefix}")
        attachment = sample.attachment
        if attachment is None:
            raise ValueError("no log-time attachment")
        (log_time_ns,) = _LOG_TIME.unpack(attachment.to_bytes())
        message = loads_json(sample.payload.to_bytes())
        if not isinstance(message, dict):
            raise ValueError(f"payload is a JSON {type(message).__name__}, not an object")
        return TelemetrySample(key[len(self._prefix) :], log_time_ns, message)

    def close(self) -> None:
        """Stop receiving. Safe to call twice."""
        if self._closed:
            return
        self._closed = True
        undeclare_quietly(self._subscriber, self._prefix)


def undeclare_quietly(subscriber: zenoh.Subscriber, key: str) -> None:
    """Undeclare on close: a failure there (session already gone) is logged, never raised."""
    try:
        subscriber.undeclare()
    except zenoh.ZError as err:
        logger.debug("undeclaring the subscriber on %s failed: %s", key, err)


def subscribe(
    session: zenoh.Session, rover_id: str, callback: Callable[[TelemetrySample], None], topic: str = "**"
) -> TelemetrySubscription:
    """Receive a rover's telemetry (one ``topic``, or all); ``callback`` runs on a Zenoh thread, so keep it
    short."""
    return TelemetrySubscription(session, rover_id, callback, topic)
