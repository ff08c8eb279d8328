"""The companion's side of the CAN bus: six wheel commands out, VESC status in, every frame recorded, the
bus load counted (``can/stats``)."""

from __future__ import annotations

import functools
import logging
import math
import threading
from collections import deque
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from operator import attrgetter
from typing import Any, NamedTuple

import can

from firmware_bridge.can_bus import BatchBus, CanConfig, open_bus
from firmware_bridge.can_echo import OwnEchoFilter, echoes_own_sends
from firmware_bridge.can_health import (
    BusLoadMeter,
    BusSignal,
    BusStateMachine,
    CanLinkState,
    ControllerLiveness,
    StateChange,
    classify_bus_state,
    classify_error_frame,
)
from firmware_bridge.errors import BridgeOperationError, FrameError
from firmware_bridge.foreign_controllers import ForeignControllers
from firmware_bridge.vesc import WHEEL_COUNT, FieldDecoder, VescCodec, erpm_command
from firmware_bridge.wheel_names import wheel_label
from logs.can_load import frame_bits
from logs.clock import Clock, to_ns
from logs.closing import ClosesOnExit
from logs.encoding import EncodedSink, bytes_only_sink
from logs.sink import MessageSink
from logs.topics import CAN_FRAMES, CAN_REJECTION_CAUSES, CAN_STATS, SAFETY_EVENTS, WHEELS_STATUS, stamp

__all__ = ["CanConfig", "CanCounters", "CanLink", "CanLinkState", "WheelReading", "WheelStatus", "open_bus"]

logger = logging.getLogger(__name__)

# Records the background repeater may hold for the loop: ~10 s of repeats at 50 Hz.
_MAX_PENDING = 4096
# The fields of each status frame the readings keep, in the order _store_status takes them.
_STATUS_FIELDS: dict[str, tuple[str, ...]] = {
    "STATUS": ("erpm", "current", "duty"),
    "STATUS_4": ("current_in",),
    "STATUS_5": ("tacho", "voltage_in"),
}
# Which FrameError reasons land in which counter.
_REJECTION_COUNTER = {"unknown_id": "unknown_id", "not_extended": "unknown_id", "wrong_dlc": "wrong_dlc"}
_TRAFFIC_COUNTERS = ("tx", "rx", "own_echoes")
# (direction, id, format, length) combinations whose JSON text a link keeps (_FrameRecords): ours are 2 x 6
# controllers x a few kinds; foreign traffic may add some, a flood of random ids must not grow it for ever.
_MAX_CACHED_FRAME_KINDS = 512
# frame_bits per (format, length), remembered: it is asked for every frame (~720 per simulated second) and
# the C-level cache lookup costs about half the Python call. Bounded: a bus delivers a handful of lengths.
_frame_bits = functools.lru_cache(maxsize=128)(frame_bits)
# An error frame's record ends with this mark (``_frame_record``'s "error": true); a data frame's has none,
# so its bytes are what they were before error frames were recorded.
_ERROR_TAIL = ',"error":true}'


@dataclass(slots=True)  # a store per status frame
class WheelReading:
    """The latest VESC status of one wheel, in physical units."""

    controller_id: int
    erpm: float = 0.0
    speed_mps: float = 0.0
    motor_current_a: float = 0.0
    duty: float = 0.0
    input_current_a: float = 0.0
    input_voltage_v: float = 0.0
    tachometer: float = 0.0
    last_status_ns: int | None = None


class WheelStatus(NamedTuple):
    """What a control tick reads of the six readings, one tuple per quantity, in wheel order
    (``CanLink.wheel_status``)."""

    status_ns: tuple[int | None, ...]  # each controller's last status time; None: never heard
    speeds_mps: tuple[float, ...]
    motor_currents_a: tuple[float, ...]
    input_voltages_v: tuple[float, ...]


# The WheelReading fields a WheelStatus holds, as C-level getters for map().
_STATUS_NS = attrgetter("last_status_ns")
_SPEED_MPS = attrgetter("speed_mps")
_MOTOR_CURRENT_A = attrgetter("motor_current_a")
_INPUT_VOLTAGE_V = attrgetter("input_voltage_v")


@dataclass
class CanCounters:
    """Link health: frames sent and received, and every rejection by cause."""

    tx: int = 0
    rx: int = 0
    own_echoes: int = 0  # our own frames the bus delivered back (udp_multicast), not counted as rx
    unknown_id: int = 0
    wrong_dlc: int = 0
    decode_errors: int = 0
    bus_errors: int = 0
    bad_commands: int = 0  # non-finite wheel speeds replaced by a stop command
    resent: int = 0  # command rounds repeated by the link to keep the controllers' timeout from firing
    stale_zeroed: int = 0  # resends that sent zero because the latest command was too old
    withheld: int = 0  # command rounds replaced by zero or not sent because of the bus state
    dropped_records: int = 0  # background-thread records lost because the loop did not poll for long

    def as_dict(self) -> dict[str, int]:
        return asdict(self)

    def link_counters(self) -> dict[str, int]:
        """Every count but the bus's own traffic (``tx``, ``rx``, ``own_echoes``): the rejections by cause
        and what the link did in the rover's place, as ``can/stats`` records them."""
        return {k: v for k, v in asdict(self).items() if k not in _TRAFFIC_COUNTERS}

    @property
    def rejected(self) -> int:
        """Received frames refused: not ours, the wrong length, or not decodable."""
        return sum(getattr(self, name) for name in CAN_REJECTION_CAUSES)


def _store_status(
    reading: WheelReading, kind: str, values: list[float], erpm_per_mps: float, t_ns: int
) -> None:
    """Keep a status frame's ``values`` (its kind's ``_STATUS_FIELDS``, in that order) in its wheel's
    reading, heard at ``t_ns``."""
    if kind == "STATUS":
        reading.erpm, reading.motor_current_a, reading.duty = values
        reading.speed_mps = reading.erpm / erpm_per_mps  # VescProfile.speed_from_erpm, inline (hot path)
    elif kind == "STATUS_4":
        (reading.input_current_a,) = values
    else:  # STATUS_5
        reading.tachometer, reading.input_voltage_v = values
    reading.last_status_ns = t_ns


def _frame_json(t_ns: int, direction: str, msg: can.Message) -> bytes:
    """``encode_message(_frame_record(t_ns, direction, msg))``, formatted directly.

    Hot path: every frame in both directions is recorded (~720 per simulated second in a lockstep
    trial, half the trial's messages), and its fields are only integers, a bool and ASCII text, so
    one format call gives the same bytes as the JSON encoder at a fifth of its cost (a test compares
    them on random frames)."""
    return (
        f'{{"timestamp":{{"sec":{t_ns // 1_000_000_000},"nsec":{t_ns % 1_000_000_000}}},'
        f'"direction":"{direction}","id":{int(msg.arbitration_id)},'
        f'"extended":{"true" if msg.is_extended_id else "false"},"dlc":{int(msg.dlc)},'
        f'"data":"{msg.data.hex()}"{_ERROR_TAIL if msg.is_error_frame else "}"}'
    ).encode()


def _frame_record(t_ns: int, direction: str, msg: can.Message) -> dict[str, object]:
    record: dict[str, object] = {
        "timestamp": stamp(t_ns),
        "direction": direction,
        "id": msg.arbitration_id,
        "extended": msg.is_extended_id,
        "dlc": msg.dlc,
        "data": msg.data.hex(),
    }
    if msg.is_error_frame:
        record["error"] = True
    return record


class _FrameRecords:
    """``_frame_record`` and ``_frame_json`` of one link's data frames (error frames: those functions
    themselves, ``CanLink._record_error_frame``), from parts kept between frames.

    Hot path (every frame in both directions, ~720 per simulated second): the frames of one poll
    share a timestamp, and a link sees a few dozen (direction, id, format, length) combinations over and
    over, so their JSON text is formatted once and each frame adds only its data (a test compares the
    results with both functions on random frames). Combinations beyond ``_MAX_CACHED_FRAME_KINDS`` (a
    flood of foreign ids) are formatted in full, as before, so the cache cannot grow without bound.
    """

    def __init__(self) -> None:
        self._t_ns: int | None = None
        self._sec = 0
        self._nsec = 0
        self._json_head = ""  # '{"timestamp":{...},' of self._t_ns
        self._json_middles: dict[tuple[str, int, bool, int], str] = {}  # '"direction":..."data":"'

    def json(self, t_ns: int, direction: str, msg: can.Message) -> bytes:
        """The frame's JSON bytes (``_frame_json``), for a sink that takes bytes alone (``BytesSink``)."""
        if t_ns != self._t_ns:
            self._start(t_ns)
        key = (direction, msg.arbitration_id, msg.is_extended_id, msg.dlc)
        middle = self._json_middles.get(key)
        if middle is None:
            middle = self._middle(key, direction, msg)
            if middle is None:
                return _frame_json(t_ns, direction, msg)
        return f'{self._json_head}{middle}{msg.data.hex()}"}}'.encode()

    def head(self, t_ns: int) -> str:
        """The JSON text of a record at ``t_ns`` before its middle: a caller that knows a frame's middle
        (``_record_middle``) already, as the link does for its own controllers' frames, makes the frame's
        ``json`` as ``f'{head}{middle}{msg.data.hex()}"}}'`` without a lookup per frame."""
        if t_ns != self._t_ns:
            self._start(t_ns)
        return self._json_head

    def format(self, t_ns: int, direction: str, msg: can.Message) -> tuple[dict[str, object], bytes]:
        """The frame's record and its JSON bytes (``encode_message`` of the record)."""
        data = self.json(t_ns, direction, msg)  # also keeps t_ns's seconds and nanoseconds
        record: dict[str, object] = {
            "timestamp": {"sec": self._sec, "nsec": self._nsec},
            "direction": direction,
            "id": msg.arbitration_id,
            "extended": msg.is_extended_id,
            "dlc": msg.dlc,
            "data": msg.data.hex(),
        }
        return record, data

    def _start(self, t_ns: int) -> None:
        """Keep the timestamp's parts and JSON text for the frames that follow at ``t_ns``."""
        self._t_ns = t_ns
        self._sec, self._nsec = divmod(t_ns, 1_000_000_000)
        self._json_head = f'{{"timestamp":{{"sec":{self._sec},"nsec":{self._nsec}}},'

    def _middle(self, key: tuple[str, int, bool, int], direction: str, msg: can.Message) -> str | None:
        """The JSON text between the timestamp and the data of a new kind, kept; None past the bound."""
        if len(self._json_middles) >= _MAX_CACHED_FRAME_KINDS:
            return None
        middle = self._json_middles[key] = _record_middle(
            direction, msg.arbitration_id, msg.is_extended_id, msg.dlc
        )
        return middle


def _record_middle(direction: str, frame_id: int, extended: bool, dlc: int) -> str:
    """The JSON text of a frame record between its timestamp and its data (``_frame_json``'s)."""
    return (
        f'"direction":"{direction}","id":{int(frame_id)},'
        f'"extended":{"true" if extended else "false"},"dlc":{int(dlc)},"data":"'
    )


class CanLink(ClosesOnExit):
    """Sends wheel speeds as VESC SET_RPM frames and collects VESC status into per-wheel readings.

    Frame timestamps in the record come from ``clock``, never from python-can (whose virtual bus stamps
    wall time). Nothing here raises on bad input from the bus: it is counted and logged.

    Commands are repeated every command period (``config.command_rate_hz``) when nobody sends a newer one,
    so the controllers' own timeout never fires in normal driving; a command older than
    ``config.command_max_age_s`` is never repeated, zero is sent instead (a stalled loop stops the rover).
    ``keep_alive()`` does the repeating (call it after the tick's own command: a round sent this instant
    is not repeated): with ``threaded=True`` a background thread calls it every period
    (real time: a stalled loop cannot stall it) and a python-can ``Notifier`` reads the bus into a buffer
    that ``poll()`` drains. Lockstep runs leave ``threaded`` off (deterministic, no threads) and call
    ``keep_alive()`` themselves if their loop is slower than the command rate.

    Bus faults (error-passive, bus-off, from error frames or ``bus.state``) change ``state`` and go to
    ``safety/events``: see ``CanLinkState`` for what each state does to wheel commands.
    """

    def __init__(
        self,
        bus: can.BusABC,
        codec: VescCodec,
        clock: Clock,
        sink: MessageSink,
        *,
        config: CanConfig | None = None,
        threaded: bool = False,
    ) -> None:
        config = config if config is not None else CanConfig()
        self._bus = bus
        self._codec = codec
        self._clock = clock
        self._sink = sink
        # A sink that takes encoded bytes gets each frame record pre-formatted (_frame_json); one that takes
        # the bytes alone (the recorder, Zenoh, a fan-out of those) gets no dict built for it either.
        self._encoded_sink = sink if isinstance(sink, EncodedSink) else None
        self._bytes_sink = bytes_only_sink(sink)
        self._frame_records = _FrameRecords()
        # For a bytes-only sink, the records (JSON bytes) of the frames of one poll or command round, all at
        # _frames_ns, formatted as each frame is taken or sent and recorded in one publish_bytes_many call
        # (_flush_frames) before anything else is published or logged.
        self._frames: list[bytes] = []
        self._frames_ns = 0
        self.profile = codec.profile
        self.counters = CanCounters()
        self._ids = codec.profile.controller_ids
        self._set_rpm = tuple(
            codec.encoder("SET_RPM", cid).fields(("erpm",)) for cid in self._ids
        )  # wheel order
        # A command round's bits (frame_bits of each SET_RPM, as the encoders make them: 29-bit ids, dlc =
        # length), counted at once when the round goes in one call (_send_batch).
        self._round_bits = sum(frame_bits(True, encoder.length) for encoder in self._set_rpm)
        # ... and the record text of each of its frames but the timestamp and the data (_FrameRecords).
        self._round_middles = tuple(
            _record_middle("tx", encoder.message.frame_id, True, encoder.length) for encoder in self._set_rpm
        )
        self._readings = [WheelReading(cid) for cid in self._ids]
        self._wheel_status: WheelStatus | None = None  # wheel_status() of the readings; None: not built
        self._wheel_of = {cid: index for index, cid in enumerate(self._ids)}
        # Frame id -> the reader of the fields the readings keep (_STATUS_FIELDS), for each controller's
        # status frames: _take's usual case, without decode's dict and VescFrame per frame.
        status_decoders: dict[int, FieldDecoder] = {
            frame_id: decoder
            for kind, names in _STATUS_FIELDS.items()
            for frame_id, decoder in codec.field_decoders(kind, names).items()
        }
        # ... as (its reader, kind, controller id, the bits of a frame the reader accepts, the wheel's
        # reading, its record's text but the timestamp and data), all _take asks per status frame in one
        # lookup. A frame the reader accepts has the message's format (a 29-bit id, as VescCodec requires,
        # and dlc = length), so its bits (frame_bits) and most of its record are known before it arrives.
        self._status_frames = {
            frame_id: (
                decoder.values,
                decoder.kind,
                decoder.controller_id,
                frame_bits(True, decoder.length),
                self._readings[self._wheel_of[decoder.controller_id]],
                _record_middle("rx", frame_id, True, decoder.length),
            )
            for frame_id, decoder in status_decoders.items()
        }
        self._foreign = ForeignControllers(self._ids)
        self._closed = False
        self._period_ns = to_ns(1.0 / config.command_rate_hz)
        self._max_age_ns = to_ns(config.command_max_age_s)
        self._bus_state = BusStateMachine(self._ids)
        silent_after_ns = to_ns(config.liveness_periods / config.status_rate_hz)
        self._liveness = ControllerLiveness(self._ids, silent_after_ns, clock.now_ns())
        self._load = BusLoadMeter(config.bitrate, clock.now_ns())
        # Bits of every frame sent or received (logs.can_load.frame_bits): the bus load's running count.
        self.bits_total = 0
        self._rejected_reported = 0  # rejections already in a warning
        self._last_rejection = ""  # the reason of the latest, for the next warning
        self._echoes = OwnEchoFilter() if echoes_own_sends(bus) else None
        # python-can's own BusABC.state is ACTIVE for ever: a bus that does not override it (socketcan,
        # virtual, the lockstep bus) tells a poll nothing there, so polls do not ask (_check_bus_state).
        self._bus_tracks_state = getattr(type(bus), "state", None) is not can.BusABC.state
        # The lockstep bus moves a command round, and everything waiting, in one call (BatchBus); the
        # background thread's reader and repeater stay frame by frame.
        self._batch_bus = bus if isinstance(bus, BatchBus) and not threaded else None
        self._zero_erpm = [0] * WHEEL_COUNT
        self._latest_erpm: list[int] = list(self._zero_erpm)
        self._latest_ns: int | None = None  # when the control loop last asked for wheel speeds
        self._last_round_ns: int | None = None  # when the link last put a command round on the bus
        self.last_sent_erpm: list[int] | None = None  # None: the last round was withheld (bus-off)
        # The background repeater shares the bus, the counters and the schedule with the loop's thread.
        self._lock = threading.RLock()
        self._background_records: deque[tuple[str, int, dict[str, Any]]] = deque(maxlen=_MAX_PENDING)
        self._reader: can.BufferedReader | None = None
        self._notifier: can.Notifier | None = None
        self._repeater: threading.Thread | None = None
        self._stop = threading.Event()
        if threaded:
            self._reader = can.BufferedReader()
            self._notifier = can.Notifier(bus, [self._reader], timeout=0.05)
            self._repeater = threading.Thread(target=self._repeat_forever, name="can-repeater", daemon=True)
            self._repeater.start()

    # --- state ---------------------------------------------------------------------------------
    @property
    def state(self) -> CanLinkState:
        """OK, ERROR_PASSIVE, BUS_OFF or RECOVERING (what each does to wheel commands: CanLinkState)."""
        return self._bus_state.state

    def controllers_alive(self) -> dict[int, bool]:
        """Controller id -> False when its STATUS has been silent for ``liveness_periods`` periods."""
        return self._liveness.alive()

    def start_watch(self, now_ns: int) -> None:
        """Count the silence of controllers not heard since ``now_ns`` from then, not from construction:
        the control loop calls this on its first tick, so a long start-up is not reported as silent
        controllers (``can_controller_silent``), nor as a ``can/stats`` window of an idle bus."""
        with self._lock:
            self._liveness.start(now_ns)
            # The bus load's first window opens here too (BusLoadMeter.restart).
            c = self.counters
            self._load.restart(now_ns, frames_total=c.tx + c.rx, bits_total=self.bits_total)

    # --- commands ------------------------------------------------------------------------------
    def send_wheel_speeds(self, speeds_mps: Sequence[float]) -> list[float]:
        """Ask for six wheel speeds (wheel order); return the ERPM the link stands for on the bus.

        Normally that is the request, rounded and clamped; while the bus is not OK it is zero (sent as
        zero, or not sent at all during bus-off).
        """
        if len(speeds_mps) != WHEEL_COUNT:
            raise BridgeOperationError(
                f"need {WHEEL_COUNT} wheel speeds in wheel order, got {len(speeds_mps)}"
            )
        erpm_per_mps = self.profile.erpm_per_mps
        requested: list[int] = []
        for index, speed in enumerate(speeds_mps):
            if not math.isfinite(speed):
                # A NaN command must never reach a motor; stopping that wheel is the safe reading of it.
                self.counters.bad_commands += 1
                logger.warning(
                    "speed %r for %s is not finite; commanding 0", speed, wheel_label(index, self._ids)
                )
                speed = 0.0
            requested.append(erpm_command(speed * erpm_per_mps))
        with self._lock:
            t_ns = self._clock.now_ns()
            self._latest_erpm = requested
            self._latest_ns = t_ns
            sent = self._send_round(t_ns, requested, background=False)
        return [float(e) for e in (sent if sent is not None else self._zero_erpm)]

    def _send_round(self, t_ns: int, erpm: list[int], *, background: bool) -> list[int] | None:
        """Put one command round on the bus as the bus state allows; return what was sent."""
        self._last_round_ns = t_ns
        state = self._bus_state.state
        if state is CanLinkState.BUS_OFF:
            self.counters.withheld += 1
            self.last_sent_erpm = None
            return None
        if state is not CanLinkState.OK:
            if erpm != self._zero_erpm:
                self.counters.withheld += 1
            erpm = self._zero_erpm
        failures = 0
        self._begin_frames(t_ns)
        try:
            if background or not self._send_batch(t_ns, erpm):
                # ``erpm`` holds erpm_command's integers (or zeros), already in the field: encoded as is.
                for set_rpm, value in zip(self._set_rpm, erpm, strict=True):
                    if not self._send(t_ns, set_rpm.encode((value,)), background=background):
                        failures += 1
        finally:
            self._flush_frames()
        self.last_sent_erpm = list(erpm)
        if failures == WHEEL_COUNT:
            # socketcan refuses every send while the interface is down or the controller is bus-off.
            self._apply(t_ns, self._bus_state.on_signal(BusSignal.BUS_OFF, "every send failed"), background)
        return erpm

    def _send_batch(self, t_ns: int, erpm: list[int]) -> bool:
        """The loop's command round in one call on a ``BatchBus``: True if every frame went (each counted
        and recorded as ``_send`` does); False if nothing was sent (no such bus, a frame that does not
        encode, the bus refusing), and the caller sends frame by frame, which counts and reports each
        failure as always.

        Hot path (a round of six SET_RPM per control tick): one send call per round, the bits of the
        round known beforehand (``_round_bits``)."""
        if self._batch_bus is None:
            return False
        try:
            msgs = [set_rpm.encode((value,)) for set_rpm, value in zip(self._set_rpm, erpm, strict=True)]
            self._batch_bus.send_all(msgs)
        except (BridgeOperationError, can.CanError):
            return False
        self.counters.tx += len(msgs)
        self.bits_total += self._round_bits
        if self._echoes is not None:
            for msg in msgs:
                self._echoes.sent(msg)
        if self._bytes_sink is not None:
            # Each frame is its encoder's, with that encoder's id, format and length: its record's middle is
            # known (_round_middles), the lookup of _FrameRecords.json is not needed.
            head = self._frame_records.head(t_ns)
            self._frames.extend(
                [
                    f'{head}{middle}{msg.data.hex()}"}}'.encode()
                    for middle, msg in zip(self._round_middles, msgs, strict=True)
                ]
            )
        else:
            for msg in msgs:
                self._publish_frame(t_ns, "tx", msg)
        return True

    def _send(self, t_ns: int, msg: can.Message, *, background: bool = False) -> bool:
        try:
            self._bus.send(msg)
        except can.CanError as err:
            self._flush_frames()  # the round's frames sent so far go before the warning on the log topic
            self.counters.bus_errors += 1
            log = logger.warning if self.counters.bus_errors == 1 else logger.debug
            log(
                "CAN send of id 0x%08x failed (%d send failures so far): %s",
                msg.arbitration_id,
                self.counters.bus_errors,
                err,
            )
            return False
        self.counters.tx += 1
        self.bits_total += _frame_bits(msg.is_extended_id, msg.dlc)
        if self._echoes is not None:
            self._echoes.sent(msg)
        if background:
            self._record(CAN_FRAMES, t_ns, _frame_record(t_ns, "tx", msg), background)
        elif self._bytes_sink is not None:  # _publish_frame's usual case, inline: six frames per tick
            self._frames.append(self._frame_records.json(t_ns, "tx", msg))
        else:
            self._publish_frame(t_ns, "tx", msg)
        return True

    def _publish_frame(self, t_ns: int, direction: str, msg: can.Message) -> None:
        if self._bytes_sink is not None:  # the caller began the batch at t_ns (_begin_frames)
            self._frames.append(self._frame_records.json(t_ns, direction, msg))
        elif self._encoded_sink is None:
            self._sink.publish(CAN_FRAMES, t_ns, _frame_record(t_ns, direction, msg))
        else:
            record, data = self._frame_records.format(t_ns, direction, msg)
            self._encoded_sink.publish_encoded(CAN_FRAMES, t_ns, record, data)

    def _begin_frames(self, t_ns: int) -> None:
        """Start collecting the frames of one poll or command round, all at ``t_ns``."""
        if self._frames:
            self._flush_frames()
        self._frames_ns = t_ns

    def _flush_frames(self) -> None:
        """Record the frames collected so far (``_frames``), in one call, in the order they came.

        Hot path: their records (formatted as each frame came) go down the sink chain in one call for a
        poll's or a command round's 6-18 frames instead of one each (with the recorder and a rate-limited
        Zenoh behind a fan-out, three calls a frame). Called before the link publishes or logs anything
        else, so the recorded order is the frames' own."""
        frames = self._frames
        if frames:
            self._frames = []
            assert self._bytes_sink is not None  # only a bytes-only sink's frames are collected
            self._bytes_sink.publish_bytes_many(CAN_FRAMES, self._frames_ns, frames)

    def keep_alive(self) -> None:
        """Repeat the latest command if a command period passed without one; zero once it is too old."""
        with self._lock:
            self._flush_background_records()
            self._repeat_if_due(self._clock.now_ns(), background=False)

    def _repeat_if_due(self, now_ns: int, *, background: bool) -> None:
        last = self._last_round_ns
        if self._closed or last is None or now_ns - last < self._period_ns:
            return
        fresh = self._latest_ns is not None and now_ns - self._latest_ns <= self._max_age_ns
        erpm = self._latest_erpm if fresh else self._zero_erpm
        if not fresh and self._latest_erpm != self._zero_erpm:
            self.counters.stale_zeroed += 1
            logger.warning(
                "no wheel command for %.0f ms (limit %.0f ms): commanding zero",
                (now_ns - (self._latest_ns or 0)) / 1e6,
                self._max_age_ns / 1e6,
            )
            self._latest_erpm = list(self._zero_erpm)
        self.counters.resent += 1
        self._send_round(now_ns, erpm, background=background)

    def _repeat_forever(self) -> None:
        while not self._stop.wait(self._period_ns / 1e9):
            with self._lock:
                try:
                    self._repeat_if_due(self._clock.now_ns(), background=True)
                except Exception:  # the repeater must outlive any one bad round; the loop sees counters
                    logger.exception("CAN command repeater failed one round")

    # --- status --------------------------------------------------------------------------------
    def poll(self) -> int:
        """Read every frame available now; update readings, liveness and bus state.

        Publishes one ``wheels/status`` if any status frame came; returns the number of frames read.
        """
        with self._lock:
            self._flush_background_records()
            t_ns = self._clock.now_ns()
            self._begin_frames(t_ns)
            # The readings may change from here (even if taking the frames fails half-way): wheel_status()
            # builds a new one when next asked.
            self._wheel_status = None
            try:
                if self._batch_bus is not None:
                    frames, status_seen = self._take_all(self._batch_bus, t_ns)
                else:
                    frames, status_seen = self._take_each(t_ns)
            finally:
                self._flush_frames()
            if self._bus_tracks_state:
                self._check_bus_state(t_ns)
            for change in self._liveness.check(t_ns):
                self._apply(t_ns, change, background=False)
            if status_seen:
                self._publish_status(t_ns)
            if t_ns >= self._load.due_ns:  # a can/stats window is over (BusLoadMeter.message): one poll in 50
                self._publish_load(t_ns)
            return frames

    def _take_each(self, t_ns: int) -> tuple[int, bool]:
        """Receive and take frames one by one until none is waiting (or the bus fails); returns how many
        came and whether any was a status frame."""
        receive = self._bus.recv if self._reader is None else self._reader.get_message
        frames = 0
        status_seen = False
        while True:
            try:
                msg = receive(timeout=0)
            except (can.CanError, OSError, ValueError) as err:
                self._receive_failed(err)
                break
            if msg is None:
                break
            frames += 1
            status_seen |= self._take(msg, t_ns)
        return frames, status_seen

    def _take_all(self, bus: BatchBus, t_ns: int) -> tuple[int, bool]:
        """``_take_each`` on a ``BatchBus``: everything waiting, received in one call (hot path: each control
        tick's poll, 6-18 frames, no receive call per frame nor for the frame that is not there)."""
        try:
            msgs = bus.recv_all()
        except (can.CanError, OSError, ValueError) as err:
            self._receive_failed(err)
            return 0, False
        if self._echoes is not None or self._bytes_sink is None:
            status_seen = False
            for msg in msgs:
                status_seen |= self._take(msg, t_ns)
            return len(msgs), status_seen
        return len(msgs), self._take_statuses(msgs, t_ns)

    def _receive_failed(self, err: Exception) -> None:
        """A receive call the bus refused: counted; the poll takes what came before it."""
        self.counters.bus_errors += 1
        logger.debug("CAN receive failed: %s", err)

    def _take_statuses(self, msgs: Sequence[can.Message], t_ns: int) -> bool:
        """``_take`` of each frame for a bytes-only sink on a bus without echoes; True if any was a status
        frame.

        Hot path (every control tick's 6-18 frames): a status frame of one of our controllers, in its
        message's format, on an OK bus, is taken here with _take's steps for it, in its order, and the
        lookups made once per poll; any other frame, and every frame while the bus is not OK, goes to
        ``_take`` itself. (``_frames`` is read per frame: recording an event flushes it.)"""
        status_seen = False
        counters, status_frames, bus_state = self.counters, self._status_frames, self._bus_state
        heard = self._liveness.heard
        erpm_per_mps = self.profile.erpm_per_mps
        head = self._frame_records.head(t_ns)
        for msg in msgs:
            status = status_frames.get(msg.arbitration_id)
            if (
                status is None
                or msg.is_error_frame
                or bus_state.state is not CanLinkState.OK
                or (values := status[0](msg)) is None
            ):
                status_seen |= self._take(msg, t_ns)
                continue
            _, kind, cid, bits, reading, middle = status
            counters.rx += 1
            # The frame has its message's id, format and length (the reader accepted it): its record is
            # _FrameRecords.json's, from the middle known beforehand.
            self._frames.append(f'{head}{middle}{msg.data.hex()}"}}'.encode())
            self.bits_total += bits
            _store_status(reading, kind, values, erpm_per_mps, t_ns)
            if (change := heard(cid, t_ns)) is not None:
                self._apply(t_ns, change, False)
            # The bus is OK (checked above; recording a liveness change does not change it): the bus state
            # machine has nothing to learn from this frame, as in _take.
            status_seen = True
        return status_seen

    def _publish_load(self, t_ns: int) -> None:
        c = self.counters
        stats = self._load.message(
            t_ns,
            tx_total=c.tx,
            rx_total=c.rx,
            bits_total=self.bits_total,
            own_echoes_total=c.own_echoes,
            link_counters=c.link_counters,
        )
        if stats is not None:
            self._sink.publish(CAN_STATS, t_ns, stats)
            self._warn_of_rejections(stats["window_s"])

    def _warn_of_rejections(self, window_s: float) -> None:
        """One warning per ``can/stats`` window that refused frames, by cause, with the last one's reason:
        each rejection alone is a debug line (a garbage flood would be thousands a second)."""
        c = self.counters
        new = c.rejected - self._rejected_reported
        if new <= 0:
            return
        self._rejected_reported = c.rejected
        causes = ", ".join(f"{name} {getattr(c, name)}" for name in CAN_REJECTION_CAUSES)
        logger.warning(
            "CAN: %d received frame(s) rejected in the last %.1f s (totals: %s); the last: %s",
            new,
            window_s,
            causes,
            self._last_rejection,
        )

    def _take(self, msg: can.Message, t_ns: int) -> bool:
        """Handle one received frame; True if it was a status frame."""
        if msg.is_error_frame:
            # Not a frame on the wire but the controller's report to its host: counted in bus_errors, not
            # rx nor the bus load; recorded (marked "error") so a recording says when the controller left
            # the bus and rejoined it, and a replay can tell the stack again (hil.replay).
            self.counters.bus_errors += 1
            self._record_error_frame(t_ns, msg)
            logger.debug("CAN error frame received (class 0x%x)", msg.arbitration_id)
            signal = classify_error_frame(msg)
            self._apply(
                t_ns, self._bus_state.on_signal(signal, f"error frame 0x{msg.arbitration_id:x}"), False
            )
            return False
        if self._echoes is not None and self._echoes.is_echo(msg):
            # Our own send coming back: it crossed the wire once, counted and recorded as tx.
            self.counters.own_echoes += 1
            return False
        self.counters.rx += 1
        if self._bytes_sink is not None:  # _publish_frame's usual case, inline: every frame comes this way
            self._frames.append(self._frame_records.json(t_ns, "rx", msg))
        else:
            self._publish_frame(t_ns, "rx", msg)
        values: list[float] | None
        status = self._status_frames.get(msg.arbitration_id)
        if status is not None and (values := status[0](msg)) is not None:
            _, kind, cid, bits, reading, _ = status
            self.bits_total += bits
        else:  # anything else, and what the decoder refuses: the codec decodes it or says why not
            self.bits_total += _frame_bits(msg.is_extended_id, msg.dlc)
            try:
                frame = self._codec.decode(msg)
            except FrameError as err:
                self._reject(msg, err)
                return False
            kind, cid = frame.kind, frame.controller_id
            fields = _STATUS_FIELDS.get(kind)
            values = None if fields is None else [frame.values[name] for name in fields]
            reading = self._readings[self._wheel_of[cid]]
        # Hot path (~420 frames per simulated second): the health machines return a change only when
        # there is one to report, so the common frame skips _apply altogether; and a good frame or a
        # status tells the bus state machine something only while the bus is not OK (bus-off: frames are
        # back; recovering: one more controller reported), so on an OK bus neither is asked.
        bus_state = self._bus_state
        if bus_state.state is not CanLinkState.OK and (change := bus_state.on_frame_received()) is not None:
            self._apply(t_ns, change, False)
        if values is None:
            return False  # not a status frame
        _store_status(reading, kind, values, self.profile.erpm_per_mps, t_ns)
        if (change := self._liveness.heard(cid, t_ns)) is not None:
            self._apply(t_ns, change, False)
        if bus_state.state is not CanLinkState.OK and (change := bus_state.on_status(cid)) is not None:
            self._apply(t_ns, change, False)
        return True

    def _record_error_frame(self, t_ns: int, msg: can.Message) -> None:
        """An error frame on ``can/frames``, in its place among the poll's frames; formatted in full (rare:
        a few a second at most, during a fault), not from ``_FrameRecords``' kept parts, whose records have
        no "error" mark."""
        if self._bytes_sink is not None:  # the poll began the batch at t_ns (_begin_frames)
            self._frames.append(_frame_json(t_ns, "rx", msg))
        elif self._encoded_sink is None:
            self._sink.publish(CAN_FRAMES, t_ns, _frame_record(t_ns, "rx", msg))
        else:
            record = _frame_record(t_ns, "rx", msg)
            self._encoded_sink.publish_encoded(CAN_FRAMES, t_ns, record, _frame_json(t_ns, "rx", msg))

    def _reject(self, msg: can.Message, err: FrameError) -> None:
        """Count a received frame the codec refused, by cause; a foreign controller is named once."""
        self._flush_frames()  # the frames so far go before a warning on the log topic
        counter = _REJECTION_COUNTER.get(err.reason, "decode_errors")
        setattr(self.counters, counter, getattr(self.counters, counter) + 1)
        self._last_rejection = str(err)
        logger.debug("rejected CAN frame: %s", err)
        if err.reason == "unknown_id":
            foreign = self._foreign.note(msg.arbitration_id, msg.is_extended_id)
            if foreign is not None:
                logger.warning("%s", foreign)

    def _check_bus_state(self, t_ns: int) -> None:
        try:
            signal = classify_bus_state(self._bus.state)
        except (NotImplementedError, can.CanError, OSError) as err:
            logger.debug("bus state unavailable: %s", err)
            return
        if signal is not BusSignal.NONE:
            self._apply(t_ns, self._bus_state.on_signal(signal, "interface reports it"), False)

    def _apply(self, t_ns: int, change: StateChange | None, background: bool) -> None:
        if change is None:
            return
        self._flush_frames()  # the frames so far go before the event and its line on the log topic
        log = logger.info if change.severity == "info" else logger.warning
        log("%s: %s", change.kind, change.detail)
        event = {
            "timestamp": stamp(t_ns),
            "kind": change.kind,
            "severity": change.severity,
            "detail": change.detail,
        }
        self._record(SAFETY_EVENTS, t_ns, event, background)

    def _record(self, topic: str, t_ns: int, message: dict[str, Any], background: bool) -> None:
        if not background:
            self._sink.publish(topic, t_ns, message)
            return
        # The sink belongs to the loop's thread; the loop publishes these at its next poll().
        if len(self._background_records) == self._background_records.maxlen:
            self.counters.dropped_records += 1
        self._background_records.append((topic, t_ns, message))

    def _flush_background_records(self) -> None:
        while self._background_records:
            topic, t_ns, message = self._background_records.popleft()
            self._sink.publish(topic, t_ns, message)

    def _publish_status(self, t_ns: int) -> None:
        wheels = [
            {
                "controller_id": r.controller_id,
                "erpm": r.erpm,
                "speed_mps": r.speed_mps,
                "motor_current_a": r.motor_current_a,
                "input_current_a": r.input_current_a,
                "duty": r.duty,
                "input_voltage_v": r.input_voltage_v,
                "tachometer": r.tachometer,
            }
            for r in self._readings
        ]
        self._sink.publish(WHEELS_STATUS, t_ns, {"timestamp": stamp(t_ns), "wheels": wheels})

    def wheel_status(self) -> WheelStatus:
        """The six readings' status times, speeds, motor currents and input voltages, in wheel order.

        Built when first asked after a poll, then the same object until the next poll (the only thing
        that changes the readings, on the loop's thread, as this runs): the control tick reads it after
        every poll that brought frames, and six ``readings()`` copies a tick were the largest cost of the
        onboard tick."""
        status = self._wheel_status
        if status is None:
            readings = self._readings
            status = self._wheel_status = WheelStatus(
                tuple(map(_STATUS_NS, readings)),
                tuple(map(_SPEED_MPS, readings)),
                tuple(map(_MOTOR_CURRENT_A, readings)),
                tuple(map(_INPUT_VOLTAGE_V, readings)),
            )
        return status

    def readings(self) -> list[WheelReading]:
        """Copies of the six readings, in wheel order (every field; the control tick reads
        ``wheel_status()``)."""
        # Built directly: dataclasses.replace inspects the fields on every call (six copies per control
        # tick made it the link's single largest cost after decoding). Positional, in WheelReading's field
        # order: binding nine keywords took two thirds of each copy (~1.2 of ~1.9 us, measured).
        return [
            WheelReading(
                r.controller_id,
                r.erpm,
                r.speed_mps,
                r.motor_current_a,
                r.duty,
                r.input_current_a,
                r.input_voltage_v,
                r.tachometer,
                r.last_status_ns,
            )
            for r in self._readings
        ]

    # --- lifetime ------------------------------------------------------------------------------
    def close(self) -> None:
        """Stop the repeater, command all six wheels to zero once whatever the bus state, then shut the
        bus down. Safe to call twice."""
        if self._closed:
            return
        self._stop.set()
        if self._repeater is not None:
            self._repeater.join()
        if self._notifier is not None:
            self._notifier.stop()
        with self._lock:
            self._closed = True
            self._flush_background_records()
            try:
                t_ns = self._clock.now_ns()
                self._begin_frames(t_ns)
                try:
                    for cid in self._ids:
                        self._send(t_ns, self._codec.encode_set_rpm(cid, 0))
                finally:
                    self._flush_frames()
                self.last_sent_erpm = list(self._zero_erpm)
            finally:
                self._bus.shutdown()
