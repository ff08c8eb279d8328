"""The figures that say what a replay changed: the estimator against the truth, and against the recording.

``rover logs replay`` prints them beside the replay's own counts (``hil.replay.ReplayResult``). The error
against the truth needs ``truth/*`` (a lockstep trial; the replay copies it); the shift from the recorded
estimate is there for every recording, a real run's too: how far the new estimate moved from the old one,
tick by tick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from logs.analysis import TrialAnalysis, analyse
from logs.reader import read_messages
from logs.topics import ESTIMATOR_POSE

# Two poses this close in log time are the same tick's (a tick is 20 ms at the default 50 Hz).
SAME_TICK_NS = 5_000_000
# (figure key in logs.analysis, label)
_ESTIMATOR_FIGURES = (
    ("estimator_position_error_rms_m", "estimator position error RMS (m, vs truth)"),
    ("estimator_position_error_max_m", "estimator position error max (m, vs truth)"),
    ("estimator_yaw_error_rms_rad", "estimator yaw error RMS (rad, vs truth)"),
)


@dataclass(frozen=True)
class ReplayFigure:
    label: str
    recorded: float | None  # the original recording's
    replayed: float | None  # the replay's


@dataclass(frozen=True)
class ReplayFigures:
    position_error_rms: ReplayFigure  # against the truth (m); None without one
    position_error_max: ReplayFigure
    yaw_error_rms: ReplayFigure  # (rad)
    # The replay's estimated position against the recording's at the same ticks (m); None: no tick in both.
    estimate_shift_rms_m: float | None
    estimate_shift_max_m: float | None

    @property
    def figures(self) -> tuple[ReplayFigure, ...]:
        """The figures against the truth, in the order they are printed."""
        return (self.position_error_rms, self.position_error_max, self.yaw_error_rms)


@dataclass(frozen=True)
class EstimateRecord:
    """What the figures need of one recording: its estimator figures and its estimated positions."""

    figures: dict[str, float | None]  # logs.analysis figure key -> value
    positions: dict[int, tuple[float, float]]  # estimator/pose by log time

    @classmethod
    def of(cls, path: Path) -> EstimateRecord:
        run = analyse(path)
        return cls({key: _figure(run, key) for key, _ in _ESTIMATOR_FIGURES}, _positions(path))


def replay_figures(recording: Path | EstimateRecord, replay: Path) -> ReplayFigures:
    """The recording and its replay analysed (``logs.analysis.analyse``) and set side by side; a sweep
    replaying one recording under several configs reads the recording once (``EstimateRecord.of``)."""
    recorded = recording if isinstance(recording, EstimateRecord) else EstimateRecord.of(recording)
    replayed = EstimateRecord.of(replay)
    error_rms, error_max, yaw_rms = (
        ReplayFigure(label, recorded.figures[key], replayed.figures[key]) for key, label in _ESTIMATOR_FIGURES
    )
    shift_rms, shift_max = _estimate_shift(recorded.positions, replayed.positions)
    return ReplayFigures(error_rms, error_max, yaw_rms, shift_rms, shift_max)


def _figure(run: TrialAnalysis, key: str) -> float | None:
    value = run.figures.get(key)
    return float(value) if value is not None and math.isfinite(value) else None


def _positions(path: Path) -> dict[int, tuple[float, float]]:
    """``estimator/pose`` positions by log time; a message without a finite position is left out."""
    positions: dict[int, tuple[float, float]] = {}
    for entry in read_messages(path, (ESTIMATOR_POSE,)):
        try:
            position = entry.message["pose"]["position"]
            x, y = float(position["x"]), float(position["y"])
        except (KeyError, TypeError, ValueError, OverflowError):  # Overflow: a number of hundreds of digits
            continue
        if math.isfinite(x) and math.isfinite(y):
            positions[entry.log_time_ns] = (x, y)
    return positions


def _estimate_shift(
    recorded: dict[int, tuple[float, float]], replayed: dict[int, tuple[float, float]]
) -> tuple[float | None, float | None]:
    """RMS and max distance between the two estimates, each replayed pose against the recorded one nearest
    in log time within ``SAME_TICK_NS``. A lockstep tick publishes both at the same reading; a `rover run`
    tick published its pose a fraction of a millisecond into the tick, where the replay's clock stands
    still at the tick's start."""
    if not recorded or not replayed:
        return None, None
    times = np.asarray(sorted(recorded), dtype=np.int64)
    shifts: list[float] = []
    for t, (x, y) in replayed.items():
        i = int(np.searchsorted(times, t))
        near = min((times[j] for j in (i - 1, i) if 0 <= j < len(times)), key=lambda c: abs(int(c) - t))
        if abs(int(near) - t) <= SAME_TICK_NS:
            old_x, old_y = recorded[int(near)]
            shifts.append(math.hypot(x - old_x, y - old_y))
    if not shifts:
        return None, None
    shift = np.asarray(shifts)
    return float(np.sqrt(np.mean(shift**2))), float(shift.max())
