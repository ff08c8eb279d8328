"""The jitter breakdown splits each sensor tick's way from the IMU's due time to the wheels into its parts,
and the send log notes only IMU frames, before they are sent."""

from __future__ import annotations

import numpy as np
import pytest

from hil.jitter_trace import SCALED_IMU_MSGID, ImuSendLog, RoverTrace, breakdown
from navigator.paced_loop import TickSample

US = 1_000
PERIOD = 20_000 * US


def test_each_part_of_the_way_is_measured_and_their_changes_add_up_to_the_period_jitter() -> None:
    due = np.array([k * PERIOD for k in range(6)], dtype=np.int64)
    send_late = np.array([100, 100, 400, 100, 100, 100]) * US  # the sensor itself late once
    sent = due + send_late
    trace = RoverTrace()
    wakes = [30, 30, 30, 500, 30, 30]  # the OS woke the rover late once
    busy = [0, 0, 0, 0, 0, 0]
    for k in range(6):
        wake = int(sent[k]) + wakes[k] * US
        rx = wake + busy[k] + 5 * US
        start = rx + 200 * US
        sample = TickSample(start, None, 900 * US, start + 600 * US - rx, "sensor", 0, rx)
        trace.last_wake_ns = wake
        trace.observe(sample)
    result = breakdown(np.array([due, sent]), trace, PERIOD)
    assert result["matched_ticks"] == 6
    parts = result["parts"]
    assert parts["send_late"]["max_ms"] == pytest.approx(0.4)
    assert parts["wake"]["max_ms"] == pytest.approx(0.5)
    assert parts["decide"]["p50_ms"] == pytest.approx(0.2)
    assert parts["compute"]["p50_ms"] == pytest.approx(0.6)
    # The late send changes the period by 0.3 ms twice (late, then back); the late wake-up by 0.47 ms.
    assert result["parts_jitter"]["send_late"]["max_ms"] == pytest.approx(0.3)
    assert result["parts_jitter"]["wake"]["max_ms"] == pytest.approx(0.47)
    # Periods: +0.3 (late send), -0.3 + 0.47 (send back, late wake), -0.47 (wake back): max 0.47 ms.
    assert result["tick_period_jitter"]["max_ms"] == pytest.approx(0.47)
    assert result["wait_returned_before_send"] == 0.0


def test_a_tick_without_a_matching_send_is_left_out() -> None:
    trace = RoverTrace()
    trace.observe(TickSample(50 * PERIOD, None, 1, 1, "sensor", 0, 50 * PERIOD - 1))  # no send near it
    trace.observe(TickSample(51 * PERIOD, None, 1, None, "deadline", 0, None))
    result = breakdown(np.array([[0], [0]]), trace, PERIOD)
    # The same keys as a run with matches, empty: a JSON reader never meets a missing key.
    assert result["matched_ticks"] == 0 and result["wait_returned_before_send"] is None
    assert result["parts"]["send_late"] == {"p50_ms": None, "p99_ms": None, "max_ms": None}
    assert result["tick_period_jitter"]["p99_ms"] is None


class _Sink:
    def __init__(self) -> None:
        self.frames: list[bytes] = []

    def write(self, data: bytes) -> None:
        self.frames.append(data)

    def read(self) -> bytes:
        return b""

    def close(self) -> None:
        pass


def test_the_send_log_notes_imu_frames_only(tmp_path) -> None:  # type: ignore[no-untyped-def]
    sink = _Sink()
    log = ImuSendLog(sink)
    imu = bytes([0xFD, 20, 0, 0, 1, 1, 191, SCALED_IMU_MSGID, 0, 0]) + bytes(22)
    heartbeat = bytes([0xFD, 9, 0, 0, 2, 1, 191, 0, 0, 0]) + bytes(11)
    log.due_ns = 123
    log.write(heartbeat)
    log.write(imu)
    assert sink.frames == [heartbeat, imu]
    log.save(tmp_path / "imu.npy")
    saved = np.load(tmp_path / "imu.npy")
    assert saved.shape == (2, 1) and saved[0, 0] == 123 and saved[1, 0] > 0
