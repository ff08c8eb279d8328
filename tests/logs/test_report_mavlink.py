"""The report sums the MAVLink link's health (``mavlink/stats``) into figures: garbage, drops, refusals."""

from __future__ import annotations

from pathlib import Path

from firmware_bridge.mavlink_health import MavlinkCounters, MavlinkHealth
from logs.analysis import analyse
from logs.recorder import McapRecorder
from logs.report import write_report
from logs.synthetic import synthetic_metadata, write_synthetic_trial

S = 1_000_000_000


def _recording(path: Path, with_stats: bool) -> Path:
    with McapRecorder(path) as recorder:
        recorder.add_metadata("scenario", synthetic_metadata(4.0))
        write_synthetic_trial(recorder, 4.0)
        if with_stats:
            # The link's own windows, as it publishes them: garbage in the 2nd and 3rd second only.
            counters = MavlinkCounters()
            health = MavlinkHealth(0, counters, link="autopilot")
            for second in range(1, 5):
                if second in (2, 3):
                    counters.bad_crc += 7
                    counters.bad_frames += 7
                    counters.dropped_bytes += 1000
                counters.signature_rejected += second == 4
                counters.scans_rejected += 2 * (second == 3)
                if second >= 3:  # a rangefinder speaks from the 3rd second: its counters appear then
                    counters.beams += 10
                    counters.beams_rejected += 3
                if second >= 2:  # a ground station talks missions from the 2nd second
                    counters.mission_messages += 4
                    counters.mission_refused += 1
                    counters.mission_timeouts += second == 4
                stats = health.report(second * S, counters).stats
                assert stats is not None
                recorder.publish("mavlink/stats", second * S, stats)
    return path


def test_report_figures_sum_the_links_windows(tmp_path: Path) -> None:
    run = analyse(_recording(tmp_path / "a.mcap", with_stats=True))
    assert run.figures["mavlink_bad_frames"] == 14
    assert run.figures["mavlink_dropped_bytes"] == 2000
    assert run.figures["mavlink_commands_refused"] == 1
    assert run.figures["mavlink_scans_refused"] == 2
    assert run.figures["mavlink_beams_refused"] == 6
    assert run.figures["mavlink_mission_refused"] == 3
    assert run.figures["mavlink_mission_timeouts"] == 1
    result = write_report([tmp_path / "a.mcap"], tmp_path / "out", plots=False)
    markdown = result.markdown.read_text("utf-8")
    assert "| MAVLink bad frames (bad CRC, header, truncated) | 14 |" in markdown
    assert "| MAVLink DISTANCE_SENSOR readings refused (unreadable) | 6 |" in markdown
    assert "| MAVLink mission operations refused | 3 |" in markdown
    assert "| MAVLink mission transfers abandoned (retries ran out) | 1 |" in markdown


def test_without_mavlink_stats_the_figures_are_unknown_not_zero(tmp_path: Path) -> None:
    run = analyse(_recording(tmp_path / "old.mcap", with_stats=False))
    assert run.figures["mavlink_bad_frames"] is None and run.figures["mavlink_dropped_bytes"] is None
    assert run.figures["mavlink_mission_refused"] is None and run.figures["mavlink_mission_timeouts"] is None
