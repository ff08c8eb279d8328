"""CAN bus load: the definitions (peak never below mean, no off-by-one) and where the report takes it from
(the link's can/stats, complete can/frames, never a thinned stream counted as complete)."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from logs.analysis import analyse
from logs.can_load import WINDOW_NS, frame_bits, load_from_frame_windows, load_from_stats
from logs.recorder import McapRecorder
from logs.sink import Message, MessageSink
from logs.telemetry_station import RateLimitedSink
from logs.topics import CAN_FRAMES, CAN_STATS, LIVE_STREAM_METADATA, MAVLINK_RAW, SENSORS_IMU, stamp

BITRATE = 1_000_000
FRAMES_PER_TICK = 12  # six SET_RPM (4 bytes) and six STATUS (8 bytes), extended ids, 50 times a second
TICK_NS = 20_000_000
BITS_PER_TICK = 6 * frame_bits(True, 4) + 6 * frame_bits(True, 8)
LOAD_PCT = 100.0 * 50 * BITS_PER_TICK / BITRATE  # 9.9 %


def _bin(times_ns: list[int], bits: list[int]) -> dict[int, int]:
    binned: dict[int, int] = {}
    for t, b in zip(times_ns, bits, strict=True):
        binned[(t - times_ns[0]) // WINDOW_NS] = binned.get((t - times_ns[0]) // WINDOW_NS, 0) + b
    return binned


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.integers(0, 10 * WINDOW_NS), min_size=2, max_size=300),
    st.lists(st.integers(47, 131), min_size=300, max_size=300),
)
def test_peak_is_never_below_mean_from_frames(times: list[int], sizes: list[int]) -> None:
    times = sorted(times)
    bits = sizes[: len(times)]
    load = load_from_frame_windows(_bin(times, bits), times[0], times[-1], BITRATE)
    if times[-1] - times[0] < WINDOW_NS:
        assert load.mean_pct is None and load.peak_pct is None
    else:
        assert load.mean_pct is not None and load.peak_pct is not None
        assert load.peak_pct > 0.0 and load.mean_pct <= load.peak_pct


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(st.floats(0.5, 2.0), st.integers(0, 500_000), st.sampled_from([250_000, 1_000_000])),
        min_size=1,
        max_size=50,
    )
)
def test_peak_is_never_below_mean_from_stats(windows: list[tuple[float, int, int]]) -> None:
    load = load_from_stats(windows)
    assert load.mean_pct is not None and load.peak_pct is not None and load.mean_pct <= load.peak_pct
    assert load.windows == len(windows)


@pytest.mark.parametrize("offset_ns", [0, 7_000_000, 19_999_999])
def test_a_steady_stream_gives_its_exact_load_whatever_the_phase(offset_ns: int) -> None:
    """Frames at both ends of the span do not count twice: 50 ticks a second is 50 ticks' bits."""
    ticks = 50 * 10 + 1  # 10 s from the first tick to the last one
    times = [offset_ns + k * TICK_NS for k in range(ticks)]
    load = load_from_frame_windows(_bin(times, [BITS_PER_TICK] * ticks), times[0], times[-1], BITRATE)
    assert load.windows == 10
    assert load.mean_pct == pytest.approx(LOAD_PCT) and load.peak_pct == pytest.approx(LOAD_PCT)


# --- the report's choice of source ---------------------------------------------------------------
def _frame(t_ns: int, dlc: int) -> dict[str, object]:
    return {
        "timestamp": stamp(t_ns),
        "direction": "tx" if dlc == 4 else "rx",
        "id": 0x301 if dlc == 4 else 0x901,
        "extended": True,
        "dlc": dlc,
        "data": "00" * dlc,
    }


def _drive(sink: MessageSink, seconds: int, *, stats: bool) -> None:
    """The link's traffic at 50 Hz, a can/stats message per second, and topics the report does not read."""
    on_bus = 0
    for tick in range(1, 50 * seconds + 1):
        t = tick * TICK_NS
        for dlc in (4,) * 6 + (8,) * 6:
            sink.publish(CAN_FRAMES, t, _frame(t, dlc))
        on_bus += FRAMES_PER_TICK
        sink.publish(SENSORS_IMU, t, {"timestamp": stamp(t)})
        if tick % 10 == 0:
            sink.publish(MAVLINK_RAW, t, {"timestamp": stamp(t)})
        if stats and tick % 50 == 0:
            bits = 50 * BITS_PER_TICK
            message = {
                "timestamp": stamp(t),
                "window_s": 1.0,
                "bitrate": BITRATE,
                "frames": 50 * FRAMES_PER_TICK,
                "bits": bits,
                "load_pct": 100.0 * bits / BITRATE,
                "tx_total": on_bus // 2,
                "rx_total": on_bus // 2,
                "own_echoes_total": 0,
            }
            sink.publish(CAN_STATS, t, message)


def _record(path: Path, *, stats: bool, thinned_hz: float | None, live: bool) -> Path:
    with McapRecorder(path) as recorder:
        if live:
            recorder.add_metadata(LIVE_STREAM_METADATA, {"rover_id": "r1"})
        sink: MessageSink = recorder
        if thinned_hz is not None:
            sink = RateLimitedSink(recorder, {CAN_FRAMES: thinned_hz})
        _drive(sink, 5, stats=stats)
    return path


def test_a_thinned_station_recording_takes_the_links_own_count(tmp_path: Path) -> None:
    run = analyse(_record(tmp_path / "station.mcap", stats=True, thinned_hz=100.0, live=True))
    assert run.figures["can_bus_load_mean_pct"] == pytest.approx(LOAD_PCT)
    assert run.figures["can_bus_load_peak_pct"] == pytest.approx(LOAD_PCT)
    assert run.figures["can_bitrate"] == BITRATE
    recorded = run.figures["can_frames_recorded_pct"]
    # 100 Hz of log time lets one frame of each 20 ms burst through: 50 of 600 a second
    assert recorded is not None and recorded == pytest.approx(100.0 * 50 / 600)
    assert run.can_load_source.startswith("can/stats") and "thinned" in run.can_load_source


def test_a_thinned_stream_without_stats_is_never_counted_as_complete(tmp_path: Path) -> None:
    run = analyse(_record(tmp_path / "old-rover.mcap", stats=False, thinned_hz=100.0, live=True))
    assert run.figures["can_bus_load_mean_pct"] is None and run.figures["can_bus_load_peak_pct"] is None
    assert run.can_load_source.startswith("none") and "thinned" in run.can_load_source


def test_the_rovers_own_complete_recording_counts_frames_without_stats(tmp_path: Path) -> None:
    run = analyse(
        _record(tmp_path / "rover.mcap", stats=False, thinned_hz=None, live=False), can_bitrate=BITRATE
    )
    assert run.figures["can_bus_load_mean_pct"] == pytest.approx(LOAD_PCT)
    assert run.figures["can_bus_load_peak_pct"] == pytest.approx(LOAD_PCT)
    assert run.can_load_source == "can/frames (every frame recorded)"


class _BusOffReports:
    """Passes every message on, with an error frame record (the controller's bus-off report, as the link
    records it) before each tenth tick's frames."""

    def __init__(self, inner: MessageSink) -> None:
        self._inner = inner
        self._last_ns = -1
        self.reports = 0

    def publish(self, topic: str, log_time_ns: int, message: Message) -> None:
        if topic == CAN_FRAMES and log_time_ns % (10 * TICK_NS) == 0 and log_time_ns != self._last_ns:
            self._last_ns = log_time_ns
            report = {**_frame(log_time_ns, 8), "id": 0x40, "extended": False, "error": True}
            self._inner.publish(CAN_FRAMES, log_time_ns, report)
            self.reports += 1
        self._inner.publish(topic, log_time_ns, message)


@pytest.mark.parametrize("stats", [True, False])
def test_error_frame_records_are_neither_frames_nor_bus_load(tmp_path: Path, stats: bool) -> None:
    """The controller's error frames were never on the wire: the report's frame count, their share of the
    link's count and the load counted from frames leave them out."""
    plain = analyse(
        _record(tmp_path / "plain.mcap", stats=stats, thinned_hz=None, live=False), can_bitrate=BITRATE
    )
    with McapRecorder(tmp_path / "bus-off.mcap") as recorder:
        reports = _BusOffReports(recorder)
        _drive(reports, 5, stats=stats)
    run = analyse(tmp_path / "bus-off.mcap", can_bitrate=BITRATE)
    assert reports.reports == 25 and run.counts[CAN_FRAMES] == plain.counts[CAN_FRAMES] + 25
    assert run.figures == plain.figures and run.can_load_source == plain.can_load_source
    assert run.figures["can_frames"] == 3000
    assert run.figures["can_bus_load_mean_pct"] == pytest.approx(LOAD_PCT)


def test_the_topic_table_lists_every_recorded_topic(tmp_path: Path) -> None:
    run = analyse(_record(tmp_path / "rover.mcap", stats=True, thinned_hz=None, live=False))
    assert run.counts == {CAN_FRAMES: 3000, CAN_STATS: 5, MAVLINK_RAW: 25, SENSORS_IMU: 250}
    assert run.counts_source == "MCAP summary"
    assert run.figures["can_frames_recorded_pct"] == pytest.approx(100.0)
    assert run.can_load_source == "can/stats (the link's own count)"


def test_a_cut_file_lists_the_topics_it_read(tmp_path: Path) -> None:
    data = _record(tmp_path / "rover.mcap", stats=True, thinned_hz=None, live=False).read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    run = analyse(cut)
    assert run.counts_source.startswith("topics read") and MAVLINK_RAW not in run.counts
    assert run.counts[CAN_FRAMES] > 0


def test_the_links_rejections_and_withheld_rounds_come_from_the_last_can_stats(tmp_path: Path) -> None:
    path = tmp_path / "rover.mcap"
    with McapRecorder(path) as recorder:
        for second, (unknown, wrong, withheld) in enumerate([(3, 1, 0), (7, 2, 5)], start=1):
            t = second * 1_000_000_000
            counters = {"unknown_id": unknown, "wrong_dlc": wrong, "decode_errors": 1, "bus_errors": 4}
            recorder.publish(
                CAN_STATS,
                t,
                {
                    "timestamp": {"sec": second, "nsec": 0},
                    "window_s": 1.0,
                    "bitrate": BITRATE,
                    "frames": 0,
                    "bits": 0,
                    "load_pct": 0.0,
                    "tx_total": 0,
                    "rx_total": 0,
                    "own_echoes_total": 0,
                    "link_counters": {**counters, "withheld": withheld},
                },
            )
    run = analyse(path)
    # Running totals: the last message's, not a sum over the messages.
    assert run.figures["can_frames_rejected"] == 7 + 2 + 1
    assert run.figures["can_rounds_withheld"] == 5
    # A recording made before the counters were recorded says it does not know.
    older = analyse(_record(tmp_path / "old.mcap", stats=True, thinned_hz=None, live=False))
    assert older.figures["can_frames_rejected"] is None and older.figures["can_rounds_withheld"] is None
