"""The link's own bus-load count (``can/stats``) and the filter for our own echoed frames."""

from __future__ import annotations

import can
import pytest

from firmware_bridge.can_bus import CanConfig
from firmware_bridge.can_echo import OwnEchoFilter
from firmware_bridge.can_health import BusLoadMeter
from firmware_bridge.can_link import CanLink
from hil.vesc_sim import SimVescBank
from logs.can_load import frame_bits
from logs.clock import SimClock, to_ns
from logs.sink import MemorySink
from logs.topics import CAN_FRAMES, CAN_STATS
from tests.firmware_bridge.virtual_can import make_codec, virtual_bus_pair


def ext(can_id: int, data: bytes) -> can.Message:
    return can.Message(arbitration_id=can_id, is_extended_id=True, data=data)


def test_meter_publishes_once_per_window_with_the_window_counts() -> None:
    meter = BusLoadMeter(bitrate=500_000, start_ns=0)
    counters = {"unknown_id": 2, "withheld": 1}
    calls = []

    def asked() -> dict[str, int]:
        calls.append(1)
        return counters

    assert (
        meter.message(
            999_999_999, tx_total=10, rx_total=10, bits_total=2_000, own_echoes_total=0, link_counters=asked
        )
        is None
    )
    first = meter.message(
        1_020_000_000, tx_total=60, rx_total=40, bits_total=13_100, own_echoes_total=3, link_counters=asked
    )
    assert first is not None
    assert first["window_s"] == pytest.approx(1.02) and first["frames"] == 100 and first["bits"] == 13_100
    assert first["load_pct"] == pytest.approx(100 * 13_100 / 1.02 / 500_000)
    assert (first["tx_total"], first["rx_total"], first["own_echoes_total"]) == (60, 40, 3)
    assert first["link_counters"] == counters and first["link_counters"] is not counters  # a copy
    assert len(calls) == 1  # asked only when the window closed, not on the poll before it
    second = meter.message(
        2_020_000_000, tx_total=70, rx_total=50, bits_total=15_720, own_echoes_total=3, link_counters=asked
    )
    assert second is not None and second["frames"] == 20 and second["bits"] == 2_620
    assert second["window_s"] == pytest.approx(1.0)


def test_meter_due_time_is_where_message_starts_giving_stats() -> None:
    """The link asks message() only from due_ns on: before it, message() gives None; at it, the stats."""
    meter = BusLoadMeter(bitrate=500_000, start_ns=5)

    def stats(now_ns: int) -> dict[str, object] | None:
        return meter.message(
            now_ns, tx_total=1, rx_total=1, bits_total=100, own_echoes_total=0, link_counters=dict
        )

    for start in (5, 3_000_000_000):
        if start != 5:
            meter.restart(start, frames_total=2, bits_total=100)
        for _ in range(2):
            due = meter.due_ns
            assert stats(due - 1) is None
            assert stats(due) is not None
            assert meter.due_ns == due + 1_000_000_000


def test_link_stats_match_the_frames_it_recorded() -> None:
    clock, sink = SimClock(1_000_000_000), MemorySink()
    config = CanConfig(bitrate=250_000)
    with virtual_bus_pair("stats") as (ours, theirs):
        bank = SimVescBank(theirs, make_codec(), clock)
        with CanLink(ours, make_codec(), clock, sink, config=config) as link:
            for _ in range(150):  # 3 s at 50 Hz
                link.send_wheel_speeds([0.5] * 6)
                bank.poll()
                bank.step(0.02)
                clock.advance(to_ns(0.02))
                link.poll()
    stats = sink.on(CAN_STATS)
    assert len(stats) == 3 and all(s["bitrate"] == 250_000 for s in stats)
    assert all(s["window_s"] == pytest.approx(1.0) for s in stats)
    topics = [topic for topic, _, _ in sink.records]
    last_stats = len(topics) - 1 - topics[::-1].index(CAN_STATS)
    up_to_last = [  # the frames recorded before the last stats (closing the link sends six more)
        frame_bits(f["extended"], f["dlc"])
        for topic, _, f in sink.records[:last_stats]
        if topic == CAN_FRAMES
    ]
    assert sum(s["bits"] for s in stats) == sum(up_to_last)
    assert sum(s["frames"] for s in stats) == len(up_to_last)
    assert stats[-1]["tx_total"] + stats[-1]["rx_total"] == len(up_to_last)
    assert stats[1]["load_pct"] == pytest.approx(100 * stats[1]["bits"] / 250_000)


def test_echo_filter_takes_each_sent_frame_back_once() -> None:
    echoes = OwnEchoFilter()
    command = ext(0x301, b"\x00\x00\x01\x00")
    echoes.sent(command)
    echoes.sent(command)
    assert not echoes.is_echo(ext(0x901, b"\x00" * 8))  # a controller's status
    assert echoes.is_echo(command) and echoes.is_echo(command)
    assert not echoes.is_echo(command)  # a third copy came from someone else


def test_echo_filter_forgets_echoes_that_never_came() -> None:
    echoes = OwnEchoFilter(capacity=4)
    for n in range(6):
        echoes.sent(ext(0x301, bytes([n])))
    assert echoes.forgotten == 2
    assert not echoes.is_echo(ext(0x301, bytes([0])))
    assert echoes.is_echo(ext(0x301, bytes([5]))) and echoes.is_echo(ext(0x301, bytes([2])))


def test_rejected_frames_are_in_can_stats_and_one_warning_per_window(
    caplog: pytest.LogCaptureFixture,
) -> None:
    clock, sink = SimClock(1_000_000_000), MemorySink()
    with virtual_bus_pair("rejections") as (ours, theirs), CanLink(ours, make_codec(), clock, sink) as link:
        for tick in range(100):  # 2 s at 50 Hz; a bad frame every tick of the first second
            if tick < 50:
                theirs.send(ext(0x0901, bytes(3)))  # STATUS of controller 1, 3 bytes instead of 8
                theirs.send(ext(0x1F07, bytes(8)))  # a controller we do not have (id 7)
            clock.advance(to_ns(0.02))
            with caplog.at_level("WARNING", logger="firmware_bridge.can_link"):
                link.poll()
    stats = sink.on(CAN_STATS)
    assert len(stats) == 2
    first, second = (s["link_counters"] for s in stats)
    assert (first["wrong_dlc"], first["unknown_id"], first["decode_errors"]) == (50, 50, 0)
    assert second == first  # nothing refused in the second window: the totals stand
    assert link.counters.rejected == 100
    warnings = [r.getMessage() for r in caplog.records if "rejected in the last" in r.getMessage()]
    # One line for the window with rejections, naming the counts by cause and the last reason; none after.
    assert len(warnings) == 1
    assert warnings[0].startswith("CAN: 100 received frame(s) rejected in the last 1.0 s")
    assert "unknown_id 50, wrong_dlc 50, decode_errors 0" in warnings[0]


def test_first_window_opens_when_the_loop_starts_not_at_construction() -> None:
    """A start-up longer than a window (kernels compiling, a slow disk) is not reported as an idle bus:
    the first ``can/stats`` window opens at the loop's first read (``start_watch``)."""
    clock, sink = SimClock(0), MemorySink()
    with virtual_bus_pair("startup") as (ours, theirs):
        bank = SimVescBank(theirs, make_codec(), clock)
        with CanLink(ours, make_codec(), clock, sink, config=CanConfig()) as link:
            clock.advance(to_ns(1.5))  # start-up: nothing sent, nothing heard
            link.start_watch(clock.now_ns())
            for _ in range(60):  # 1.2 s at 50 Hz
                link.poll()
                link.send_wheel_speeds([0.5] * 6)
                bank.poll()
                bank.step(0.02)
                clock.advance(to_ns(0.02))
    stats = sink.on(CAN_STATS)
    assert len(stats) == 1
    assert stats[0]["timestamp"] == {"sec": 2, "nsec": 500_000_000}  # 1 s after the loop's start
    assert stats[0]["window_s"] == pytest.approx(1.0)
    assert stats[0]["frames"] > 0 and stats[0]["load_pct"] > 0.0
