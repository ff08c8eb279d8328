"""``rover hil soak``'s printout: what the judge decided, including the failsafes a peer stall explains."""

from __future__ import annotations

from pathlib import Path

import pytest

import hil.soak
from hil.soak_report import PeerTiming, SoakReport
from rover_cli.main import main


def _report(**fields: object) -> SoakReport:
    base: dict[str, object] = {
        "seconds": 60.0,
        "seed": 1,
        "faults": [],
        "memory": [],
        "ticks": 2000,
        "sensor_ticks": 1500,
        "deadline_ticks": 500,
        "overruns": 0,
        "crashes": [],
    }
    base.update(fields)
    return SoakReport(**base)  # type: ignore[arg-type]


def _run(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, report: SoakReport) -> int:
    monkeypatch.setattr(hil.soak, "run_soak", lambda settings: report)
    return main(["hil", "soak", "--minutes", "1", "--out", str(tmp_path)])


def test_prints_the_rover_start_and_the_stall_failsafes_apart_from_the_unexplained(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    report = _report(
        rover_first_tick_s=21.3,
        stall_failsafes=["failsafe.wheel_silent at 30.9 s: the peer stalled 250 ms at 30.6 s"],
        unexplained_failsafes=["failsafe.gps_lost at 40.0 s"],
    )
    assert _run(monkeypatch, tmp_path, report) == 1  # an unexplained failsafe is a problem
    out = " ".join(capsys.readouterr().out.split())  # rich wraps long lines
    assert "times in s from the rover's first wheel command; rover's first tick at 21.3 s" in out
    assert "failsafes a stall of the peer explains: 1" in out
    assert "failsafe.wheel_silent at 30.9 s: the peer stalled 250 ms" in out
    assert "failsafes no planned fault explains: 1" in out
    assert "NOT OK" in out


def test_a_stall_explained_failsafe_alone_leaves_the_soak_ok(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    report = _report(
        stall_failsafes=["failsafe.wheel_silent at 30.9 s: the peer stalled 250 ms"],
        peer=PeerTiming(3, 2, 2200.0, 2140.0, stalls_before_start=1, longest_soak_stall_ms=250.0),
    )
    assert _run(monkeypatch, tmp_path, report) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "stalls 2, 1 of them before the rover's first command (not judged) (2200 ms" in out
    assert "rover's first tick never" in out
    assert "failsafes no planned fault explains: none" in out
    assert "NOT OK" not in out
