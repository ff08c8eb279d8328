"""Fault injection on the wires: the simulator's end of the CAN bus and of the MAVLink link.

Both wrappers sit on the simulator's side, so a fault hits both directions, as a broken cable would:
commands from the rover and status / sensor data to it. A bus-off is also the rover's own controller's
state: ``hil.bus_off`` gives the rover's end that (in lockstep its sends fail; in real time the peer sends
it the error frames Linux would).
Random choices come from a generator of their own, so injecting a fault does not shift the sensor noise of
the rest of the trial.
"""

from __future__ import annotations

import logging
from collections import deque
from typing import Any

import can
import numpy as np

from firmware_bridge.mavlink_transport import Transport
from hil.faults import FaultSchedule
from logs.clock import Clock, to_ns

logger = logging.getLogger(__name__)


class FaultyCanBus(can.BusABC):
    """Wraps the simulator's CAN bus end and applies the schedule's ``can`` faults to every frame."""

    def __init__(
        self, inner: can.BusABC, faults: FaultSchedule, clock: Clock, rng: np.random.Generator
    ) -> None:
        super().__init__(channel=getattr(inner, "channel_info", "faulty"))
        self.channel_info = f"faulty:{inner.channel_info}"
        self._inner = inner
        self._faults = faults
        self._clock = clock
        self._rng = rng
        self._held_in: deque[tuple[int, can.Message]] = deque()  # (due ns, frame) toward the simulator
        self._held_out: deque[tuple[int, can.Message]] = deque()  # toward the rover
        self.dropped = 0
        self.corrupted = 0
        self.delayed = 0

    def _filter(self, msg: can.Message, now: int, held: deque[tuple[int, can.Message]]) -> can.Message | None:
        """The frame as it survives the active faults, or None (dropped or held back)."""
        for fault in self._faults.active_all("can", now):
            if fault.kind == "off":
                self.dropped += 1
                return None
            if fault.kind == "intermittent" and self._rng.random() < fault.probability:
                self.dropped += 1
                return None
            if fault.kind == "garbage" and self._rng.random() < fault.probability:
                msg = _corrupted(msg, self._rng)
                self.corrupted += 1
            if fault.kind == "delayed" and fault.delay_s > 0.0:
                held.append((now + to_ns(fault.delay_s), msg))
                self.delayed += 1
                return None
        return msg

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        now = self._clock.now_ns()
        self._release(self._held_out, now)
        passed = self._filter(msg, now, self._held_out)
        if passed is not None:
            self._inner.send(passed, timeout)

    def _release(self, held: deque[tuple[int, can.Message]], now: int) -> None:
        while held and held[0][0] <= now:
            self._inner.send(held.popleft()[1])

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        now = self._clock.now_ns()
        self._release(self._held_out, now)
        if self._held_in and self._held_in[0][0] <= now:
            return self._held_in.popleft()[1], False
        while True:
            msg = self._inner.recv(timeout=0)
            if msg is None:
                return None, False
            passed = self._filter(msg, now, self._held_in)
            if passed is not None:
                return passed, False

    def shutdown(self) -> None:
        # The inner bus belongs to whoever opened it (the lockstep wiring shuts it down); this wrapper is
        # the world's, which shuts it (hil.world.SimWorld.close).
        super().shutdown()


def _corrupted(msg: can.Message, rng: np.random.Generator) -> can.Message:
    """The frame with one payload byte flipped (CRC escaped) or, if it has none, its length changed."""
    data = bytearray(msg.data)
    if data:
        data[int(rng.integers(len(data)))] ^= 0xFF
        dlc = msg.dlc
    else:
        data = bytearray(b"\xff")
        dlc = 1
    return can.Message(
        arbitration_id=msg.arbitration_id,
        is_extended_id=msg.is_extended_id,
        data=bytes(data),
        dlc=dlc,
        timestamp=msg.timestamp,
    )


class FaultyTransport:
    """Wraps the simulator's MAVLink transport and applies the schedule's ``mavlink`` faults."""

    def __init__(
        self, inner: Transport, faults: FaultSchedule, clock: Clock, rng: np.random.Generator
    ) -> None:
        self._inner = inner
        self._faults = faults
        self._clock = clock
        self._rng = rng
        self.bytes_dropped = 0
        self.chunks_corrupted = 0

    def write(self, data: bytes) -> None:
        fault = self._faults.active("mavlink", self._clock.now_ns())
        if fault is not None and fault.kind == "off":
            self.bytes_dropped += len(data)
            return
        if fault is not None and fault.kind == "garbage" and data and self._rng.random() < fault.probability:
            corrupted = bytearray(data)
            corrupted[int(self._rng.integers(len(corrupted)))] ^= 0xFF
            data = bytes(corrupted)
            self.chunks_corrupted += 1
        self._inner.write(data)

    def read(self) -> bytes:
        data = self._inner.read()
        fault = self._faults.active("mavlink", self._clock.now_ns(), "off")
        if fault is not None:
            self.bytes_dropped += len(data)
            return b""
        return data

    def close(self) -> None:
        self._inner.close()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)
