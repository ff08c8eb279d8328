"""The companion's side of the CAN bus: six wheel commands out, VESC status in, every frame recorded."""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from types import TracebackType

import can

from firmware_bridge.can_bus import CanConfig, open_bus
from firmware_bridge.errors import BridgeOperationError, FrameError
from firmware_bridge.vesc import WHEEL_COUNT, VescCodec, VescFrame, erpm_command
from logs.clock import Clock
from logs.sink import MessageSink
from logs.topics import CAN_FRAMES, WHEELS_STATUS, stamp

__all__ = ["CanConfig", "CanCounters", "CanLink", "WheelReading", "open_bus"]

logger = logging.getLogger(__name__)

_STATUS_KINDS = frozenset({"STATUS", "STATUS_4", "STATUS_5"})
# Which FrameError reasons land in which counter.
_REJECTION_COUNTER = {"unknown_id": "unknown_id", "not_extended": "unknown_id", "wrong_dlc": "wrong_dlc"}


@dataclass
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


@dataclass
class CanCounters:
    """Link health: frames sent and received, and every rejection by cause."""

    tx: int = 0
    rx: int = 0
    unknown_id: int = 0
    wrong_dlc: int = 0
    decode_errors: int = 0
    bus_errors: int = 0
    bad_commands: int = 0  # non-finite wheel speeds replaced by a stop command

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


def _frame_record(t_ns: int, direction: str, msg: can.Message) -> dict[str, object]:
    return {
        "timestamp": stamp(t_ns),
        "direction": direction,
        "id": msg.arbitration_id,
        "extended": msg.is_extended_id,
        "dlc": msg.dlc,
        "data": bytes(msg.data).hex(),
    }


class CanLink:
    """Sends wheel speeds as VESC SET_RPM frames and collects VESC status into per-wheel readings.

    Frame timestamps in the record come from ``clock``, never from python-can (whose virtual bus stamps
    wall time). Nothing here raises on bad input from the bus: it is counted and logged.
    """

    def __init__(self, bus: can.BusABC, codec: VescCodec, clock: Clock, sink: MessageSink) -> None:
        self._bus = bus
        self._codec = codec
        self._clock = clock
        self._sink = sink
        self.profile = codec.profile
        self.counters = CanCounters()
        self._ids = codec.profile.controller_ids
        self._readings = [WheelReading(cid) for cid in self._ids]
        self._wheel_of = {cid: index for index, cid in enumerate(self._ids)}
        self._closed = False

    # --- commands ------------------------------------------------------------------------------
    def send_wheel_speeds(self, speeds_mps: Sequence[float]) -> list[float]:
        """Send six SET_RPM frames in wheel order; return the ERPM sent (after rounding and clamping)."""
        if len(speeds_mps) != WHEEL_COUNT:
            raise BridgeOperationError(
                f"need {WHEEL_COUNT} wheel speeds in wheel order, got {len(speeds_mps)}"
            )
        erpm_per_mps = self.profile.erpm_per_mps
        t_ns = self._clock.now_ns()
        sent: list[float] = []
        for cid, speed in zip(self._ids, speeds_mps, strict=True):
            if not math.isfinite(speed):
                # A NaN command must never reach a motor; stopping that wheel is the safe reading of it.
                self.counters.bad_commands += 1
                logger.warning("wheel speed %r for controller %d is not finite; commanding 0", speed, cid)
                speed = 0.0
            erpm = erpm_command(speed * erpm_per_mps)
            sent.append(float(erpm))
            self._send(t_ns, self._codec.encode_set_rpm(cid, erpm))
        return sent

    def _send(self, t_ns: int, msg: can.Message) -> None:
        try:
            self._bus.send(msg)
        except can.CanError as err:
            self.counters.bus_errors += 1
            log = logger.warning if self.counters.bus_errors == 1 else logger.debug
            log(
                "CAN send of id 0x%08x failed (%d send failures so far): %s",
                msg.arbitration_id,
                self.counters.bus_errors,
                err,
            )
            return
        self.counters.tx += 1
        self._sink.publish(CAN_FRAMES, t_ns, _frame_record(t_ns, "tx", msg))

    # --- status --------------------------------------------------------------------------------
    def poll(self) -> int:
        """Read every frame available now and update the readings.

        Publishes one ``wheels/status`` if any status frame came; returns the number of frames read.
        """
        t_ns = self._clock.now_ns()
        frames = 0
        status_seen = False
        while True:
            try:
                msg = self._bus.recv(timeout=0)
            except can.CanError as err:
                self.counters.bus_errors += 1
                logger.debug("CAN receive failed: %s", err)
                break
            if msg is None:
                break
            frames += 1
            if msg.is_error_frame:
                # Error frames carry no data worth recording as a frame; the counter is their record.
                self.counters.bus_errors += 1
                logger.debug("CAN error frame received (id 0x%x)", msg.arbitration_id)
                continue
            self.counters.rx += 1
            self._sink.publish(CAN_FRAMES, t_ns, _frame_record(t_ns, "rx", msg))
            try:
                frame = self._codec.decode(msg)
            except FrameError as err:
                counter = _REJECTION_COUNTER.get(err.reason, "decode_errors")
                setattr(self.counters, counter, getattr(self.counters, counter) + 1)
                logger.debug("rejected CAN frame: %s", err)
                continue
            if frame.kind in _STATUS_KINDS:
                self._apply_status(frame, t_ns)
                status_seen = True
        if status_seen:
            self._publish_status(t_ns)
        return frames

    def _apply_status(self, frame: VescFrame, t_ns: int) -> None:
        reading = self._readings[self._wheel_of[frame.controller_id]]
        values = frame.values
        if frame.kind == "STATUS":
            reading.erpm = values["erpm"]
            reading.speed_mps = self.profile.speed_from_erpm(reading.erpm)
            reading.motor_current_a = values["current"]
            reading.duty = values["duty"]
        elif frame.kind == "STATUS_4":
            reading.input_current_a = values["current_in"]
        else:  # STATUS_5
            reading.tachometer = values["tacho"]
            reading.input_voltage_v = values["voltage_in"]
        reading.last_status_ns = t_ns

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

    def readings(self) -> list[WheelReading]:
        """Copies of the six readings, in wheel order."""
        return [replace(r) for r in self._readings]

    # --- lifetime ------------------------------------------------------------------------------
    def close(self) -> None:
        """Command all six wheels to zero once, then shut the bus down. Safe to call twice."""
        if self._closed:
            return
        self._closed = True
        try:
            self.send_wheel_speeds([0.0] * WHEEL_COUNT)
        finally:
            self._bus.shutdown()

    def __enter__(self) -> CanLink:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
