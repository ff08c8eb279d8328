"""The ground station's side of the live stream: record it into MCAP, keep a live view of the rover, and
thin the rover's stream to configured rates.

``StreamRecorder`` writes every received sample into an ``McapRecorder`` with the rover's log time, so the
ground-station file reads back like the rover's own (same topics, payloads and log times; ``rover logs
report`` works on it), marked as a live-stream recording (``LIVE_STREAM_METADATA``) because its topics may
be thinned. ``LiveView`` keeps the latest pose, speed, both modes (guidance's and the safety
supervisor's), active failsafes, goal, health, CAN bus load and when the rover was last heard for
``rover telemetry watch``. ``RateLimitedSink`` sits in front of the Zenoh publisher on the rover: per-topic
maximum rates judged on log time, so lockstep trials stay deterministic; ``can/stats`` is never thinned.

The bus load shown is the rover link's own count (``can/stats``): the live ``can/frames`` are usually
thinned, so counting them would understate it. Without ``can/stats`` (an older rover) the view counts the
frames it receives and says that this is a lower bound.
"""

from __future__ import annotations

import logging
import math
import threading
from collections import deque
from collections.abc import Mapping, Sequence
from typing import NoReturn

import zenoh

from logs.can_load import WINDOW_NS, frame_bits
from logs.clock import Clock, to_ns
from logs.encoding import EncodedSink, bytes_only_sink
from logs.errors import LogsError, TelemetryError, TelemetrySetupError
from logs.recorder import McapRecorder
from logs.sink import Message, MessageSink
from logs.telemetry import NEVER_THINNED, TelemetrySample, TelemetrySubscription, subscribe
from logs.topics import (
    CAN_FRAMES,
    CAN_STATS,
    ESTIMATOR_POSE,
    LIVE_STREAM_METADATA,
    NAVIGATOR_STATE,
    SAFETY_EVENTS,
    TOPICS,
    TRUTH_POSE,
    yaw_of,
)

logger = logging.getLogger(__name__)

# The rover publishes navigator/state every tick (~20 Hz, thinned to a few Hz at most): two seconds of
# silence is a link or a rover in trouble, not a quiet moment.
STALE_AFTER_S = 2.0
LAST_HEARD = "last heard"


# Before any message of a thinned topic, its next one is due from the earliest time there is.
_FIRST_PASSES = -(2**63)


class RateLimitedSink:
    """Forwards at most ``rates[topic]`` messages per second of log time; topics not listed pass freely."""

    def __init__(self, sink: MessageSink, rates_hz: Mapping[str, float]) -> None:
        for topic, rate in rates_hz.items():
            if topic not in TOPICS:
                raise TelemetrySetupError(f"telemetry rate for unknown topic {topic!r}")
            if topic in NEVER_THINNED:
                raise TelemetrySetupError(
                    f"{topic} is never thinned (the ground station's bus load comes from it; ~1 message/s): "
                    "remove it from [zenoh.rates]"
                )
            if not math.isfinite(rate) or rate <= 0.0:
                raise TelemetrySetupError(f"telemetry rate for {topic} must be > 0 Hz, got {rate!r}")
        self._sink = sink
        self._sink_encoded = sink if isinstance(sink, EncodedSink) else None
        self._sink_bytes = bytes_only_sink(sink)
        # BytesSink (logs.encoding): bytes alone will do when the sink behind takes bytes alone.
        self.records_bytes_only = self._sink_bytes is not None
        # Thinned topic -> [log time from which its next message passes, period in ns]. Every thinned topic
        # is a key from the start (the first message always passes), so one lookup tells a topic that is
        # not thinned (most of them) from one that is and gives a thinned one's whole state: a dropped
        # message costs that lookup and a comparison, a passed one a store more.
        self._thinned: dict[str, list[int]] = {
            topic: [_FIRST_PASSES, int(1e9 / rate)] for topic, rate in rates_hz.items()
        }
        self.dropped = 0

    def publish(self, topic: str, log_time_ns: int, message: Message) -> None:
        if self._due(topic, log_time_ns):
            self._sink.publish(topic, log_time_ns, message)

    def publish_encoded(self, topic: str, log_time_ns: int, message: Message, data: bytes) -> None:
        """As ``publish``, passing the already encoded bytes on when the sink behind takes them."""
        if not self._due(topic, log_time_ns):
            return
        if self._sink_encoded is not None:
            self._sink_encoded.publish_encoded(topic, log_time_ns, message, data)
        else:
            self._sink.publish(topic, log_time_ns, message)

    def publish_bytes(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """As ``publish``, for a message's bytes alone (only when ``records_bytes_only``)."""
        sink = self._sink_bytes
        if sink is None:
            _refuse_bytes(topic)
        # _due, inline: with the recorder and Zenoh behind a fan-out every message of a trial comes this way.
        thinned = self._thinned.get(topic)
        if thinned is not None:
            if log_time_ns < thinned[0]:
                self.dropped += 1
                return
            thinned[0] = log_time_ns + thinned[1]
        sink.publish_bytes(topic, log_time_ns, data)

    def publish_bytes_many(self, topic: str, log_time_ns: int, datas: Sequence[bytes]) -> None:
        """As ``publish_bytes`` for each of ``datas`` in turn, decided once: they share one log time, so
        at most the first can pass a thinned topic (the next is due a period later); every one passes a
        topic that is not thinned, or one whose period rounds to 0 ns."""
        sink = self._sink_bytes
        if sink is None:
            _refuse_bytes(topic)
        thinned = self._thinned.get(topic)
        if thinned is None or not datas:
            sink.publish_bytes_many(topic, log_time_ns, datas)
            return
        if log_time_ns < thinned[0]:
            self.dropped += len(datas)
            return
        period = thinned[1]
        thinned[0] = log_time_ns + period
        if period == 0:
            sink.publish_bytes_many(topic, log_time_ns, datas)
            return
        self.dropped += len(datas) - 1
        sink.publish_bytes(topic, log_time_ns, datas[0])

    def _due(self, topic: str, log_time_ns: int) -> bool:
        thinned = self._thinned.get(topic)
        if thinned is None:
            return True  # not thinned
        if log_time_ns < thinned[0]:
            self.dropped += 1
            return False
        thinned[0] = log_time_ns + thinned[1]
        return True


def _refuse_bytes(topic: str) -> NoReturn:
    raise TelemetryError(
        "this rate limiter's sink needs each message itself, not only its bytes (records_bytes_only "
        f"is False); cannot pass on {topic!r} as bytes"
    )


class StreamRecorder:
    """Records a rover's live stream into ``recorder`` (the caller's; closed by the caller)."""

    def __init__(self, session: zenoh.Session, rover_id: str, recorder: McapRecorder) -> None:
        self._recorder = recorder
        self._lock = threading.Lock()  # zenoh calls back on its own threads; the recorder is not thread-safe
        self.recorded = 0
        self.failed = 0
        self.topics: set[str] = set()
        recorder.add_metadata(
            LIVE_STREAM_METADATA,
            {
                "rover_id": rover_id,
                "note": "recorded from the live stream; topics may be thinned ([zenoh.rates])",
            },
        )
        self._subscription: TelemetrySubscription = subscribe(session, rover_id, self._on_sample)

    @property
    def rejected(self) -> int:
        return self._subscription.rejected

    def _on_sample(self, sample: TelemetrySample) -> None:
        with self._lock:
            try:
                self._recorder.publish(sample.topic, sample.log_time_ns, sample.message)
            except LogsError as err:
                self.failed += 1
                if self.failed <= 10:
                    logger.warning("live sample on %s not recorded: %s", sample.topic, err)
                return
            self.recorded += 1
            self.topics.add(sample.topic)

    def close(self) -> None:
        self._subscription.close()
        with self._lock:  # a callback in flight finishes before the caller closes the recorder
            pass


class LiveView:
    """Latest state of one rover from its stream; ``rows()`` for a table. Thread-safe.

    Guidance's mode and the safety supervisor's are shown side by side (``navigator/state``): guidance
    may be DRIVING while the supervisor holds the wheels. The active failsafes are the rover's own list
    (``navigator/state``'s ``failsafes``), so a view started after a failsafe fired still shows it.
    "last heard" is judged on ``clock`` (the station's), not on the rover's log time: a rover that went
    silent keeps its last log time forever.
    """

    def __init__(
        self, clock: Clock, bitrate: int | None = None, stale_after_s: float = STALE_AFTER_S
    ) -> None:
        """``bitrate`` (the rover config's, when the station has it) is used only without ``can/stats``."""
        self._lock = threading.Lock()
        self._clock = clock
        self._stale_after_ns = to_ns(stale_after_s)
        self._values: dict[str, str] = {}
        self._bitrate = bitrate
        self._stats: tuple[float, int] | None = None  # the latest can/stats: load %, bitrate
        self._can_frames: deque[tuple[int, int]] = deque()  # (log time, bits) of the last second
        self._can_bits = 0
        self._heard_ns: int | None = None  # station clock at the last sample
        self.samples = 0

    def update(self, sample: TelemetrySample) -> None:
        message = sample.message
        heard = self._clock.now_ns()
        with self._lock:
            self.samples += 1
            self._heard_ns = heard
            try:
                self._take(sample.topic, sample.log_time_ns, message)
            except (KeyError, TypeError, ValueError):
                self._values["last problem"] = f"unusable {sample.topic} message"
            self._values["log time (s)"] = f"{sample.log_time_ns / 1e9:.2f}"

    def _take(self, topic: str, t_ns: int, message: Message) -> None:
        if topic == ESTIMATOR_POSE or (topic == TRUTH_POSE and "pose (estimate)" not in self._values):
            p = message["pose"]["position"]
            label = "pose (estimate)" if topic == ESTIMATOR_POSE else "pose (truth)"
            heading = math.degrees(yaw_of(message["pose"]))
            x, y = float(p["x"]), float(p["y"])  # "z": a value that rounds to zero reads 0.00, not -0.00
            self._values[label] = f"x {x:z.2f} m, y {y:z.2f} m, yaw {heading:z.0f} deg"
            self._values["speed (m/s)"] = f"{float(message['speed_mps']):z.2f}"
            if topic == ESTIMATOR_POSE:
                self._values["estimator"] = "healthy" if message.get("healthy") else "NOT healthy"
        elif topic == NAVIGATOR_STATE:
            self._take_state(message)
        elif topic == SAFETY_EVENTS:
            self._values["last safety event"] = (
                f"{message['severity']}: {message['kind']} {message['detail']}"
            )
        elif topic == CAN_STATS:
            self._stats = (float(message["load_pct"]), int(message["bitrate"]))
        elif topic == CAN_FRAMES:
            if message.get("error") is True:
                return  # an error frame: the controller's report, no bits on the wire
            bits = frame_bits(bool(message["extended"]), int(message["dlc"]))
            self._can_frames.append((t_ns, bits))
            self._can_bits += bits
            while self._can_frames and self._can_frames[0][0] <= t_ns - WINDOW_NS:
                self._can_bits -= self._can_frames.popleft()[1]

    def _take_state(self, message: Message) -> None:
        # Parsed whole before anything is shown, so a bad message leaves the previous state standing.
        limit = f"{float(message['speed_limit_mps']):.2f} m/s ({message['speed_limit_reason']})"
        xte = message.get("cross_track_error_m")
        goal = message.get("goal")
        gx, gy = (_finite(goal.get("x")), _finite(goal.get("y"))) if isinstance(goal, dict) else (None, None)
        safety = message.get("safety_mode")
        failsafes = message.get("failsafes")
        values = {
            "mode (guidance)": str(message["mode"]),
            # An older rover does not publish the supervisor's mode; its speed-limit reason names a hold.
            "mode (safety)": (
                "n/a (older rover: see the speed limit's reason)" if safety is None else str(safety)
            ),
            "failsafes active": (
                "n/a (older rover: see the safety events)"
                if failsafes is None
                else ", ".join(str(f) for f in failsafes) or "none"
            ),
            "speed limit": limit,
            # The rover sends NaN (null in JSON) for "no goal".
            "goal": "none" if gx is None or gy is None else f"({gx:.2f}, {gy:.2f})",
            "cross-track error (m)": "n/a" if xte is None else f"{float(xte):.2f}",
        }
        self._values.update(values)

    def heard_ago_s(self) -> float | None:
        """Seconds since the last sample (station clock); ``None`` when nothing was heard."""
        with self._lock:
            heard = self._heard_ns
        return None if heard is None else (self._clock.now_ns() - heard) / 1e9

    def stale(self) -> bool:
        """Nothing heard at all, or nothing for longer than ``stale_after_s``."""
        ago = self.heard_ago_s()
        return ago is None or ago > self._stale_after_ns / 1e9

    def bus_load_pct(self) -> float | None:
        """The rover's own bus load over its last window (``can/stats``); ``None`` until one arrives."""
        with self._lock:
            return None if self._stats is None else self._stats[0]

    def _bus_load_row(self) -> str:
        if self._stats is not None:
            load, bitrate = self._stats
            return f"{load:.1f} (rover's count at {bitrate / 1000:.0f} kbit/s)"
        if not self._can_frames:
            return "n/a (no can/stats or can/frames yet)"
        if self._bitrate is None:
            return (
                f"n/a (no can/stats; {len(self._can_frames)} can/frames in the last second, may be thinned)"
            )
        load = 100.0 * self._can_bits / self._bitrate
        return f">= {load:.1f} (no can/stats: counted from can/frames, which may be thinned)"

    def rows(self) -> list[tuple[str, str]]:
        ago = self.heard_ago_s()
        if ago is None:
            heard = "never: nothing received from the rover yet"
        else:
            heard = f"{ago:.1f} s ago" + (" (STALE)" if self.stale() else "")
        with self._lock:
            rows = [(LAST_HEARD, heard), *sorted(self._values.items())]
            rows.append(("CAN bus load (%)", self._bus_load_row()))
        return rows


def _finite(value: object) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return None
    return float(value)


def rate_limited(sink: MessageSink, rates_hz: tuple[tuple[str, float], ...]) -> MessageSink:
    """``sink`` thinned to the configured per-topic rates (``ZenohSettings.rates_hz``), or as is."""
    return RateLimitedSink(sink, dict(rates_hz)) if rates_hz else sink
