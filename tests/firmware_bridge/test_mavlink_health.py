"""MAVLink garbage is counted by kind, recorded on ``mavlink/stats``, and named in a rate-limited WARNING;
datagrams are parsed one by one; a flood beyond the receive budget is dropped unread and counted."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_budget import ReceiveBudget, admit_datagrams, starts_like_a_frame
from firmware_bridge.mavlink_link import ImuSample, MavlinkLink
from firmware_bridge.mavlink_transport import memory_pipe_pair
from logs.clock import SimClock
from logs.sink import MemorySink
from logs.topics import MAVLINK_STATS, TOPICS

SECOND = 1_000_000_000
_sender = mavlink2.MAVLink(None, 1, 1)


def frame(msg: mavlink2.MAVLink_message) -> bytes:
    return bytes(msg.pack(_sender))


def imu(k: int = 0) -> bytes:
    return frame(mavlink2.MAVLink_scaled_imu_message(k, 0, 0, -1000, 0, 0, 0, 0, 0, 0, 0))


def bad_crc() -> bytes:
    data = bytearray(imu())
    data[-1] ^= 0xFF
    return bytes(data)


def unknown_id() -> bytes:
    """A well-formed MAVLink 2 frame of a message id the common dialect does not have (42 000)."""
    msgid = 42_000
    payload = b"\x01\x02\x03"
    header = bytes([0xFD, len(payload), 0, 0, 7, 1, 1, msgid & 0xFF, msgid >> 8 & 0xFF, msgid >> 16])
    return header + payload + b"\x00\x00"  # its CRC cannot be checked without the message's CRC extra


NOISE = b"\x00\x11\x22\x33hello"


class FakeDatagrams:
    """A transport that keeps datagram boundaries, as UDP does."""

    def __init__(self) -> None:
        self.queued: list[bytes] = []

    def write(self, data: bytes) -> None:
        del data

    def read(self) -> bytes:
        return b"".join(self.read_datagrams())

    def read_datagrams(self) -> list[bytes]:
        datagrams, self.queued = self.queued, []
        return datagrams

    def close(self) -> None:
        pass


def test_garbage_is_counted_by_kind_and_recorded_once_a_second() -> None:
    ours, autopilot = memory_pipe_pair()
    clock, sink = SimClock(), MemorySink()
    link = MavlinkLink(ours, clock, sink)
    autopilot.write(NOISE + bad_crc() + unknown_id() + imu())
    readings = link.poll()
    assert [type(r) for r in readings] == [ImuSample]
    assert sink.on(MAVLINK_STATS) == []  # the first window is not over yet
    clock.advance(SECOND)
    link.poll()
    clock.advance(SECOND)
    link.poll()
    first, second = sink.on(MAVLINK_STATS)
    assert first["link"] == "autopilot" and first["window_s"] == pytest.approx(1.0)
    assert (first["bad_crc"], first["bad_header"], first["truncated"]) == (1, 0, 0)
    # Each byte once: the noise, and the bad frame (its bytes after the start marker were looked at again
    # for a frame starting inside it, found none, and count as noise).
    assert first["bad_frames"] == 1 and first["bad_bytes"] == len(NOISE) + len(bad_crc())
    assert first["noise_bytes"] == len(NOISE) + len(bad_crc()) - 1
    assert first["unknown_frames"] == 1 and first["rx_frames"] == 2  # the unknown one and the IMU
    # The next window saw nothing; the totals carry on.
    assert second["bad_frames"] == 0 and second["rx_frames"] == 0
    assert second["bad_frames_total"] == 1 and second["rx_frames_total"] == 2
    required = TOPICS[MAVLINK_STATS].schema["required"]
    assert sorted(first) == sorted(required)


def test_a_warning_names_the_garbage_at_most_once_per_five_seconds(caplog: pytest.LogCaptureFixture) -> None:
    ours, autopilot = memory_pipe_pair()
    clock = SimClock()
    link = MavlinkLink(ours, clock, MemorySink())
    caplog.set_level(logging.WARNING, logger="firmware_bridge.mavlink_link")
    for _ in range(50):  # 5 s of 10 Hz polls, garbage in every one
        autopilot.write(bad_crc() + bad_crc() + NOISE + imu())
        link.poll()
        clock.advance(SECOND // 10)
    link.poll()
    (warning,) = [r.getMessage() for r in caplog.records if "MAVLink" in r.getMessage()]
    skipped = 50 * (2 * len(bad_crc()) + len(NOISE))
    assert warning == (
        f"MAVLink autopilot link: 100 bad frames (bad CRC 100); {skipped} bytes skipped "
        f"({skipped - 100} of them noise between frames) in the last 5.0 s"
    )
    caplog.clear()
    for _ in range(60):  # a clean link, and frames of an unknown id (a real autopilot's dialect): quiet
        autopilot.write(unknown_id() + imu())
        link.poll()
        clock.advance(SECOND // 10)
    assert [r for r in caplog.records if "MAVLink" in r.getMessage()] == []


def test_garbage_in_one_datagram_does_not_swallow_the_frame_in_the_next() -> None:
    transport = FakeDatagrams()
    link = MavlinkLink(transport, SimClock(), MemorySink())
    # The garbage ends in the start of a frame header announcing a 48-byte payload of an unknown id: read as
    # one stream, that header takes the IMU frame of the next datagram in as its payload.
    transport.queued = [NOISE + bytes([0xFD, 48, 0, 0, 1, 1, 1, 0xAA, 0xBB]), imu()]
    readings = link.poll()
    assert [type(r) for r in readings] == [ImuSample]
    assert link.counters.truncated == 1 and link.counters.unknown_frames == 0


def test_a_datagram_flood_over_the_budget_is_dropped_counted_and_the_frames_still_parsed() -> None:
    rng = np.random.default_rng(3)
    noise = [rng.integers(0, 256, 1000, dtype=np.uint8).tobytes() for _ in range(100)]
    noise = [d for d in noise if not starts_like_a_frame(d)]
    transport = FakeDatagrams()
    clock = SimClock()
    link = MavlinkLink(transport, clock, MemorySink(), rx_budget_bytes_per_s=100_000)  # 10 kB burst
    transport.queued = [*noise[:50], imu(1), *noise[50:]]
    readings = link.poll()
    assert [type(r) for r in readings] == [ImuSample]
    # The IMU datagram first, then as many noise datagrams as fit in the rest: nine.
    assert link.counters.dropped_bytes == (len(noise) - 9) * 1000
    assert link.counters.bad_bytes <= 9 * 1000
    # A tenth of a second later the budget has refilled by 10 kB: the next IMU frame gets through again.
    clock.advance(SECOND // 10)
    transport.queued = [*noise, imu(2)]
    assert [type(r) for r in link.poll()] == [ImuSample]


def test_a_stream_flood_keeps_the_newest_bytes() -> None:
    ours, autopilot = memory_pipe_pair()
    link = MavlinkLink(ours, SimClock(), MemorySink(), rx_budget_bytes_per_s=100_000)
    # Noise without start markers: in a stream, a stray header could take the frame after it in as its
    # payload (an unknown id cannot be checked), which no budget changes.
    flood = np.random.default_rng(4).integers(0, 0xFD, 50_000, dtype=np.uint8).tobytes()
    autopilot.write(flood + imu())
    assert [type(r) for r in link.poll()] == [ImuSample]
    assert link.counters.dropped_bytes == len(flood) + len(imu()) - 10_000


def test_receive_budget_accrues_with_the_clock_up_to_its_burst() -> None:
    budget = ReceiveBudget(1000, start_ns=0, burst_s=0.5)
    assert budget.allowance(0) == 500
    budget.spend(500)
    assert budget.allowance(SECOND // 10) == 100
    assert budget.allowance(10 * SECOND) == 500


def test_frame_like_datagrams_go_first_within_the_allowance() -> None:
    kept, dropped = admit_datagrams([NOISE, imu(), NOISE, imu()], allowance=2 * len(imu()) + len(NOISE))
    assert kept == [NOISE, imu(), imu()] and dropped == len(NOISE)
