"""Replay many recordings under several configs and set the configs side by side (``rover logs replay``
with more than one recording or config).

The tuning question is rarely about one run: "does a larger GPS noise help across the whole campaign, or
only on sandy ground?" Each recording is replayed once per config (``hil.replay``), each replay analysed
against its recording (``hil.replay_figures``), and each config gets one row: the estimator's error against
the truth averaged over the recordings that have a truth, how far its estimate moved from the recorded one,
and how many wheel commands differ. A recording that cannot be replayed is named with the reason and left
out of every row, so the rows stay comparable.
"""

from __future__ import annotations

import logging
import math
import multiprocessing
import statistics
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path

from hil.replay import ReplayResult, replay_recording
from hil.replay_figures import EstimateRecord, ReplayFigures, replay_figures
from hil.scenario import Scenario
from logs.errors import LogsError
from logs.warn_once import each_message_once
from navigator.config import RoverConfig

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SweepConfig:
    name: str  # unique among the sweep's configs: the file's stem, numbered when two share one
    config: RoverConfig


@dataclass(frozen=True)
class SweepReplay:
    recording: Path
    config: str
    result: ReplayResult
    figures: ReplayFigures


@dataclass(frozen=True)
class SweepRow:
    """One config over every recording replayed under all configs."""

    config: str
    source: str
    recordings: int
    with_truth: int  # recordings whose estimator error against the truth is known (lockstep trials)
    error_rms_mean_m: float | None  # mean over those of the position error RMS
    error_max_m: float | None  # the largest position error of any of them
    yaw_error_rms_mean_rad: float | None
    recorded_error_rms_mean_m: float | None  # the same recordings' own, for scale
    shift_rms_mean_m: float | None  # mean over all recordings of the shift from the recorded estimate
    wheel_commands_differing_pct: float  # of all ticks compared
    wheel_speed_difference_max_mps: float  # the largest difference of one wheel's commanded speed


@dataclass
class SweepResult:
    rows: list[SweepRow] = field(default_factory=list)
    replays: list[SweepReplay] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)  # recording -> why it was left out


def sweep_names(paths: Sequence[Path]) -> list[str]:
    """Each config's name in the sweep: its stem, with ``-2``, ``-3`` ... for a stem met again."""
    names: list[str] = []
    for path in paths:
        name, number = path.stem, 2
        while name in names:
            name, number = f"{path.stem}-{number}", number + 1
        names.append(name)
    return names


def replay_sweep(
    recordings: Sequence[Path],
    configs: Sequence[SweepConfig],
    out_dir: Path,
    *,
    scenario: Scenario | None = None,
    workers: int = 1,
    on_done: Callable[[Path], None] | None = None,
) -> SweepResult:
    """Replay every recording under every config into ``out_dir``; ``on_done(recording)`` after each
    recording's replays.

    Each replay goes to ``out_dir/<NNN>-<recording's folder>-<stem>/<config>.mcap``, NNN the recording's
    place in the list (campaign recordings are all ``trial.mcap``). ``workers`` > 1: recordings are replayed
    in that many worker processes (``spawn``, as a campaign's trials); the result is the same, in the same
    order."""
    jobs = [
        _Job(recording, configs, out_dir / _folder_name(index, recording), scenario)
        for index, recording in enumerate(recordings, start=1)
    ]
    outcomes: dict[int, _Outcome] = {}
    if workers <= 1 or len(jobs) <= 1:
        for index, job in enumerate(jobs):
            outcomes[index] = _replay_job(job)
            if on_done is not None:
                on_done(job.recording)
    else:
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=context) as pool:
            futures = {pool.submit(_replay_job, job): index for index, job in enumerate(jobs)}
            for future in as_completed(futures):
                index = futures[future]
                try:
                    outcomes[index] = future.result()
                except BrokenProcessPool:
                    outcomes[index] = _Outcome([], _LOST)
                if on_done is not None:
                    on_done(jobs[index].recording)
    result = SweepResult()
    for index, job in enumerate(jobs):
        outcome = outcomes[index]
        if outcome.error is not None:
            result.failed[str(job.recording)] = outcome.error
        else:
            result.replays.extend(outcome.replays)
    result.rows = [_row(entry, [r for r in result.replays if r.config == entry.name]) for entry in configs]
    return result


def _folder_name(index: int, recording: Path) -> str:
    return f"{index:03d}-{recording.parent.name or 'recording'}-{recording.stem}"


_LOST = (
    "a worker process died (killed, out of memory, or a crash outside Python) before this recording was "
    "replayed; the others still waiting were lost with it"
)


@dataclass(frozen=True)
class _Job:
    recording: Path
    configs: Sequence[SweepConfig]
    folder: Path
    scenario: Scenario | None


@dataclass(frozen=True)
class _Outcome:
    replays: list[SweepReplay]
    error: str | None  # why the recording is left out of every row; None: replayed under every config


def _replay_job(job: _Job) -> _Outcome:
    """One recording under every config (in a worker, or inline); never raises: a failure is an outcome."""
    try:
        with each_message_once("logs.reader"):  # one notice of a cut recording, not one per pass
            return _replay_under_every_config(job)
    except LogsError as err:
        # One config failing the recording leaves it out of every row, so each row has the same runs.
        return _Outcome([], str(err))
    except Exception as err:  # a bug must not take the other recordings down; it is logged and named
        _log.exception("replay of %s failed", job.recording)
        return _Outcome([], repr(err))


def _replay_under_every_config(job: _Job) -> _Outcome:
    replays: list[SweepReplay] = []
    recorded: EstimateRecord | None = None
    for entry in job.configs:
        replayed = replay_recording(
            job.recording, entry.config, job.folder / f"{entry.name}.mcap", scenario=job.scenario
        )
        # Read once, after the first replay has found the file readable and replayable.
        recorded = recorded or EstimateRecord.of(job.recording)
        figures = replay_figures(recorded, replayed.out_path)
        replays.append(SweepReplay(job.recording, entry.name, replayed, figures))
    return _Outcome(replays, None)


def _row(entry: SweepConfig, replays: list[SweepReplay]) -> SweepRow:
    def known(values: list[float | None]) -> list[float]:
        return [v for v in values if v is not None and math.isfinite(v)]

    errors = known([r.figures.position_error_rms.replayed for r in replays])
    recorded = known([r.figures.position_error_rms.recorded for r in replays])
    maxima = known([r.figures.position_error_max.replayed for r in replays])
    yaws = known([r.figures.yaw_error_rms.replayed for r in replays])
    shifts = [r.figures.estimate_shift_rms_m for r in replays if r.figures.estimate_shift_rms_m is not None]
    compared = sum(r.result.wheel_commands_compared for r in replays)
    differing = sum(r.result.wheel_commands_differing for r in replays)
    return SweepRow(
        config=entry.name,
        source=entry.config.source,
        recordings=len(replays),
        with_truth=len(errors),
        error_rms_mean_m=_mean(errors),
        error_max_m=max(maxima) if maxima else None,
        yaw_error_rms_mean_rad=_mean(yaws),
        recorded_error_rms_mean_m=_mean(recorded),
        shift_rms_mean_m=_mean(shifts),
        wheel_commands_differing_pct=100.0 * differing / compared if compared else 0.0,
        wheel_speed_difference_max_mps=max(
            (r.result.wheel_speed_difference_max_mps for r in replays), default=0.0
        ),
    )


def _mean(values: list[float]) -> float | None:
    return statistics.fmean(values) if values else None
