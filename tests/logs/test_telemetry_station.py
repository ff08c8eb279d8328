"""Rate limiting of the live stream and the ground station's live view (no network needed)."""

from __future__ import annotations

import pytest

from logs.can_load import frame_bits
from logs.clock import SimClock
from logs.errors import TelemetrySetupError
from logs.sink import MemorySink
from logs.telemetry import TelemetrySample
from logs.telemetry_station import LiveView, RateLimitedSink
from logs.topics import CAN_FRAMES, CAN_STATS, ESTIMATOR_POSE, LOG, NAVIGATOR_STATE, planar_pose, stamp


def test_rate_limit_is_judged_on_log_time() -> None:
    memory = MemorySink()
    sink = RateLimitedSink(memory, {ESTIMATOR_POSE: 10.0})
    for tick in range(100):  # 50 Hz for 2 s
        t = tick * 20_000_000
        sink.publish(ESTIMATOR_POSE, t, {"i": tick})
        sink.publish(LOG, t, {"i": tick})  # not limited
    assert len(memory.on(ESTIMATOR_POSE)) == 20 and len(memory.on(LOG)) == 100
    assert [m["i"] for m in memory.on(ESTIMATOR_POSE)][:3] == [0, 5, 10]
    assert sink.dropped == 80


@pytest.mark.parametrize("rates", [{"no/such": 1.0}, {LOG: 0.0}, {LOG: float("nan")}, {CAN_STATS: 100.0}])
def test_bad_rates_are_setup_errors(rates: dict[str, float]) -> None:
    with pytest.raises(TelemetrySetupError):
        RateLimitedSink(MemorySink(), rates)


def _frame(dlc: int = 8) -> dict[str, object]:
    return {"extended": True, "dlc": dlc}


def test_live_view_shows_latest_state() -> None:
    view = LiveView(SimClock())
    pose = {"pose": planar_pose(1.0, 2.0, 0.0), "speed_mps": 0.5, "healthy": True}
    view.update(TelemetrySample(ESTIMATOR_POSE, 1_000, pose))
    state = {
        "mode": "DRIVING",
        "speed_limit_mps": 0.8,
        "speed_limit_reason": "slope",
        "cross_track_error_m": None,
        "timestamp": stamp(0),
    }
    view.update(TelemetrySample(NAVIGATOR_STATE, 2_000, state))
    view.update(TelemetrySample(ESTIMATOR_POSE, 3_000, {"pose": "broken"}))  # counted, not raised
    rows = dict(view.rows())
    assert rows["pose (estimate)"].startswith("x 1.00 m, y 2.00 m")
    assert rows["mode (guidance)"] == "DRIVING" and rows["estimator"] == "healthy"
    assert rows["speed limit"] == "0.80 m/s (slope)" and rows["cross-track error (m)"] == "n/a"
    assert rows["last problem"] == f"unusable {ESTIMATOR_POSE} message"
    # An older rover's state has no supervisor mode: the view says so rather than guessing.
    assert rows["mode (safety)"].startswith("n/a") and rows["goal"] == "none"


def _state(**fields: object) -> dict[str, object]:
    state: dict[str, object] = {
        "mode": "DRIVING",
        "goal": {"x": 11.5, "y": 7.5},
        "speed_limit_mps": 0.0,
        "speed_limit_reason": "safety hold",
        "cross_track_error_m": 0.123,
        "safety_mode": "HOLD",
        "failsafes": ["gps_lost", "wheel_silent"],
    }
    state.update(fields)
    return state


def test_live_view_shows_a_rover_at_rest_without_minus_signs() -> None:
    # An estimate's speed of -0.001 m/s while standing still read "-0.00".
    view = LiveView(SimClock())
    pose = {"pose": planar_pose(-0.001, 2.0, 0.0), "speed_mps": -0.001, "healthy": True}
    view.update(TelemetrySample(ESTIMATOR_POSE, 1_000, pose))
    rows = dict(view.rows())
    assert rows["speed (m/s)"] == "0.00" and rows["pose (estimate)"].startswith("x 0.00 m, y 2.00 m")


def test_live_view_shows_the_supervisors_hold_next_to_guidances_driving() -> None:
    view = LiveView(SimClock())
    view.update(TelemetrySample(NAVIGATOR_STATE, 1, _state(speed_limit_mps=1 / 3)))
    rows = dict(view.rows())
    assert rows["mode (guidance)"] == "DRIVING" and rows["mode (safety)"] == "HOLD"
    assert rows["failsafes active"] == "gps_lost, wheel_silent"
    assert rows["speed limit"] == "0.33 m/s (safety hold)"
    assert rows["goal"] == "(11.50, 7.50)" and rows["cross-track error (m)"] == "0.12"

    view.update(TelemetrySample(NAVIGATOR_STATE, 2, _state(safety_mode="DRIVING", failsafes=[])))
    rows = dict(view.rows())
    assert rows["mode (safety)"] == "DRIVING" and rows["failsafes active"] == "none"
    view.update(TelemetrySample(NAVIGATOR_STATE, 3, _state(goal={"x": None, "y": None}, mode="IDLE")))
    assert dict(view.rows())["goal"] == "none"
    # A state that cannot be read leaves the last good one standing, and says so.
    view.update(TelemetrySample(NAVIGATOR_STATE, 4, _state(speed_limit_mps="fast", mode="NO_PATH")))
    rows = dict(view.rows())
    assert rows["mode (guidance)"] == "IDLE" and rows["last problem"] == f"unusable {NAVIGATOR_STATE} message"


def test_live_view_says_when_the_rover_was_last_heard_and_turns_stale() -> None:
    clock = SimClock()
    view = LiveView(clock, stale_after_s=2.0)
    assert view.stale() and dict(view.rows())["last heard"].startswith("never")
    view.update(TelemetrySample(NAVIGATOR_STATE, 10**12, _state()))  # the rover's log time is not ours
    clock.advance(1_500_000_000)
    assert not view.stale() and dict(view.rows())["last heard"] == "1.5 s ago"
    clock.advance(1_000_000_000)
    assert view.stale() and dict(view.rows())["last heard"] == "2.5 s ago (STALE)"
    view.update(TelemetrySample(NAVIGATOR_STATE, 10**12 + 1, _state()))
    assert not view.stale() and dict(view.rows())["last heard"] == "0.0 s ago"


def test_live_view_shows_the_rovers_own_bus_load_whatever_the_stream_thinned() -> None:
    view = LiveView(SimClock(), bitrate=1_000_000)
    for i in range(100):  # the thinned stream: 100 frames a second
        view.update(TelemetrySample(CAN_FRAMES, i * 10_000_000, _frame()))
    stats = {"load_pct": 8.48, "bitrate": 1_000_000, "window_s": 1.0, "bits": 84_800}
    view.update(TelemetrySample(CAN_STATS, 1_000_000_000, stats))
    assert view.bus_load_pct() == pytest.approx(8.48)
    assert dict(view.rows())["CAN bus load (%)"] == "8.5 (rover's count at 1000 kbit/s)"


def test_live_view_without_stats_never_shows_frames_as_the_whole_load() -> None:
    view = LiveView(SimClock(), bitrate=500_000)
    assert dict(view.rows())["CAN bus load (%)"].startswith("n/a")
    for i in range(1500):  # 1500 frames over 1.5 s: 1000 in the last second
        view.update(TelemetrySample(CAN_FRAMES, i * 1_000_000, _frame()))
    assert view.bus_load_pct() is None
    row = dict(view.rows())["CAN bus load (%)"]
    load = 100.0 * 1000 * frame_bits(True, 8) / 500_000
    assert row == f">= {load:.1f} (no can/stats: counted from can/frames, which may be thinned)"
    no_bitrate = LiveView(SimClock())
    no_bitrate.update(TelemetrySample(CAN_FRAMES, 0, _frame()))
    assert "may be thinned" in dict(no_bitrate.rows())["CAN bus load (%)"]


def test_live_view_counts_no_bits_for_the_controllers_error_frames() -> None:
    view = LiveView(SimClock(), bitrate=500_000)
    for i in range(1000):  # 1000 frames in the last second, and a bus-off report beside every tenth
        view.update(TelemetrySample(CAN_FRAMES, i * 1_000_000, _frame()))
        if i % 10 == 0:
            error = {"extended": False, "dlc": 8, "error": True}
            view.update(TelemetrySample(CAN_FRAMES, i * 1_000_000, error))
    load = 100.0 * 1000 * frame_bits(True, 8) / 500_000
    assert dict(view.rows())["CAN bus load (%)"].startswith(f">= {load:.1f} ")


def test_a_rover_config_thinning_can_stats_is_refused_on_load(tmp_path) -> None:  # type: ignore[no-untyped-def]
    # Refused when the file is read, naming the key: `rover run` once got as far as opening Zenoh,
    # failed there with a traceback and then hung at exit with the session still open.
    from logs.settings import ConfigError
    from navigator.config import load_rover_config

    path = tmp_path / "rover.toml"
    path.write_text('[zenoh.rates]\n"can/stats" = 10.0\n', encoding="utf-8")
    with pytest.raises(ConfigError, match="never thinned") as refused:
        load_rover_config(path)
    assert refused.value.key == "zenoh.rates.can/stats"
