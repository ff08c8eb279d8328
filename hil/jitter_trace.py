"""Where the sensor-paced loop's jitter comes from: per tick, the IMU's send, the rover's wake-up and tick.

``CLOCK_MONOTONIC`` is system-wide, so the simulated autopilot (another process) and the rover read the
same clock. The peer wraps its MAVLink transport in ``ImuSendLog``, which notes, for each SCALED_IMU
frame it writes, when the frame was due (the peer's step deadline) and when ``sendto`` was called; the rover
side notes, per tick, when its wait last returned (``RoverTrace``) and the tick's ``TickSample``. The
sample's receive time is matched to the latest IMU send at or before it, and its way to the wheels is
split into:

* ``send_late``: the IMU frame left this long after it was due (the peer's wake-up overshoot and the
  encoding before it): the sensor's own timing;
* ``wake``: from the send to the rover's wait returning (``sendto``, loopback and the OS waking the rover);
* ``busy``: from the later of the send and the wake-up to the receive time (the rover was doing
  something else: reading other links, waiting for the GIL, a tick);
* ``decide``: receive time to tick start; ``compute``: tick start to the wheel commands (the latency's
  rest).

Each is summarised as it is (p50 / p99 / max) and as its change between consecutive sensor ticks, which
is what it adds to the period jitter: ``period - nominal = Δdue + Δsend_late + Δwake + Δbusy + Δdecide``
with ``Δdue`` the IMU's own nominal period minus the control period (0 at 50 Hz).

This is a diagnostic (``rover bench runtime --trace``); nothing in the loop depends on it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from firmware_bridge.mavlink_transport import Transport
from navigator.paced_loop import TickSample
from navigator.runtime import percentiles_ms

SCALED_IMU_MSGID = 26
_MAVLINK2_MAGIC = 0xFD
# A receive matched to a send longer ago than this is not that send's (a lost frame, a stall).
_MATCH_WINDOW_NS = 10_000_000


def _is_imu_frame(data: bytes) -> bool:
    """A MAVLink 2 frame's message id is bytes 7-9, little-endian."""
    return (
        len(data) >= 10
        and data[0] == _MAVLINK2_MAGIC
        and data[7] | data[8] << 8 | data[9] << 16 == (SCALED_IMU_MSGID)
    )


class ImuSendLog:
    """A MAVLink transport that notes, per SCALED_IMU frame written, when it was due and when it left.

    The peer sets ``due_ns`` before each step. ``save(path)`` writes both columns (``.npy``, ns).
    """

    def __init__(self, inner: Transport) -> None:
        self._inner = inner
        self.due_ns = 0
        self._due: list[int] = []
        self._sent: list[int] = []

    def write(self, data: bytes) -> None:
        if _is_imu_frame(data):
            # Noted before ``sendto``: on loopback the datagram is in the rover's socket before the call
            # returns, and a busy-polling rover can read it before this process reads the clock again.
            self._sent.append(time.monotonic_ns())
            self._due.append(self.due_ns)
        self._inner.write(data)

    def read(self) -> bytes:
        return self._inner.read()

    def close(self) -> None:
        self._inner.close()

    def save(self, path: Path) -> None:
        np.save(path, np.array([self._due, self._sent], dtype=np.int64).reshape(2, -1))


@dataclass
class RoverTrace:
    """The rover's side: when its wait (or busy-poll) last returned, and every tick."""

    last_wake_ns: int = 0
    ticks: list[tuple[int, TickSample]] = field(default_factory=list)

    def wrap_wait(self, wait: Callable[[float], None]) -> Callable[[float], None]:
        def traced(seconds: float) -> None:
            wait(seconds)
            self.last_wake_ns = time.monotonic_ns()

        return traced

    def wrap_poll(self, poll: Callable[[], bool]) -> Callable[[], bool]:
        def traced() -> bool:
            ready = poll()
            if ready:
                self.last_wake_ns = time.monotonic_ns()
            return ready

        return traced

    def observe(self, sample: TickSample) -> None:
        self.ticks.append((self.last_wake_ns, sample))


def breakdown(imu: np.ndarray, rover: RoverTrace, nominal_period_ns: int) -> dict[str, Any]:
    """Split each sensor tick's way from the IMU's due time to the wheel command (see the module doc).

    ``imu``: shape (2, N), rows due and sent (ns), as ``ImuSendLog.save`` wrote them.
    """
    due, sent = imu[0], imu[1]
    rows: list[tuple[int, int, int, int, int, int, int]] = []
    for wake, sample in rover.ticks:
        if sample.trigger_ns is None or sample.latency_ns is None:
            continue
        rx = sample.trigger_ns
        index = int(np.searchsorted(sent, rx, side="right")) - 1
        if index < 0 or rx - sent[index] > _MATCH_WINDOW_NS:
            continue
        rows.append(
            (int(due[index]), int(sent[index]), wake, rx, sample.start_ns, rx + sample.latency_ns, index)
        )
    # The same keys however few ticks matched (a short or stalled run): empty parts summarise as None.
    table = np.array(rows, dtype=np.int64).reshape(-1, 7)
    due_t, sent_t, wake_t, rx_t, start_t, command_t, index_t = table.T
    woke_after_send = np.maximum(wake_t, sent_t)
    parts = {
        "send_late": sent_t - due_t,
        "wake": np.maximum(wake_t - sent_t, 0),
        "busy": rx_t - woke_after_send,
        "decide": start_t - rx_t,
        "compute": command_t - start_t,
    }
    # Consecutive sensor ticks on consecutive IMU frames only: a skipped frame is not jitter of a part.
    consecutive = np.diff(index_t) == 1
    period = np.diff(start_t)[consecutive]
    result: dict[str, Any] = {
        "matched_ticks": len(rows),
        "imu_frames": int(sent.size),
        "imu_period_jitter": percentiles_ms(np.abs(np.diff(sent) - nominal_period_ns)),
        "tick_period_jitter": percentiles_ms(np.abs(period - nominal_period_ns)),
        "parts": {name: percentiles_ms(values) for name, values in parts.items()},
        "parts_jitter": {
            name: percentiles_ms(np.abs(np.diff(values)[consecutive]))
            for name, values in parts.items()
            if name != "compute"
        },
        "wait_returned_before_send": float(np.mean(wake_t < sent_t)) if len(rows) else None,
    }
    return result
