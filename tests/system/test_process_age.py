"""`rover hil trial`'s "wall time in all" counts from the process's start, as `time` does."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from rover_cli.hil_commands import _wall_time_line
from rover_cli.process_age import process_age_s


def _stat_line(name: str, start_ticks: int) -> str:
    # pid (name) state, then fields 4..21, then the start time (field 22), then more.
    return f"4242 ({name}) S " + " ".join(["0"] * 18) + f" {start_ticks} 1 2 3\n"


def test_the_age_is_the_boot_clock_less_the_start_time_whatever_the_name(tmp_path: Path) -> None:
    tick = os.sysconf("SC_CLK_TCK")
    now = time.clock_gettime(time.CLOCK_BOOTTIME)
    started_ticks = int((now - 5.0) * tick)  # five seconds ago
    stat = tmp_path / "stat"
    stat.write_text(_stat_line("rover (hil) 1", started_ticks), encoding="ascii")
    age = process_age_s(stat)
    assert age is not None and 5.0 <= age < 5.0 + 2.0 / tick + 1.0


def test_no_proc_says_nothing(tmp_path: Path) -> None:
    assert process_age_s(tmp_path / "missing") is None
    garbled = tmp_path / "stat"
    garbled.write_text("4242 (rover) S 1 2", encoding="ascii")
    assert process_age_s(garbled) is None


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="no /proc here")
def test_this_process_is_older_than_its_tests_and_younger_than_a_day() -> None:
    age = process_age_s()
    assert age is not None and 0.0 < age < 86_400.0


def test_the_line_says_what_it_counts() -> None:
    assert _wall_time_line(2.25, 1.56, 4.08).startswith("wall time: 4.08 s in all since the process started")
    fallback = _wall_time_line(2.25, 1.56, None)
    assert fallback.startswith("wall time: 2.25 s for the trial") and "not counted" in fallback
