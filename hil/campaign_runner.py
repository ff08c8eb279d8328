"""Running a campaign: every trial in a worker process, one MCAP each, then the summary tables.

Workers are separate processes (``spawn``: a clean interpreter per worker, nothing inherited from the
parent's threads), so a campaign uses every core and a trial that raises is recorded as failed without
stopping the others. A worker process that dies (killed, out of memory, a crash outside Python) breaks the
pool, which then runs nothing more: its trial and every one not finished yet are recorded as errors, and
the summary is still written for those that finished. Each trial's numbers come from its own
``metrics.json``, computed from its MCAP.
"""

from __future__ import annotations

import json
import logging
import multiprocessing
import time
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.campaign import Campaign, TrialSpec, campaign_config
from hil.campaign_place import CampaignPlace
from hil.campaign_summary import others_sentence, write_summary
from hil.scenario import load_scenario, with_perception
from hil.trial_log_label import trial_log_label

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class TrialOutcome:
    spec: TrialSpec
    ok: bool
    end_reason: str
    success: bool
    failures: tuple[str, ...]
    metrics_path: Path | None
    simulated_s: float
    wall_s: float
    error: str = ""


def run_one(spec: TrialSpec) -> TrialOutcome:
    """Run one campaign trial (in a worker); never raises, a failure is an outcome."""
    from hil.trial import run_trial  # imported in the worker: the parent only schedules

    started = time.perf_counter()
    try:
        with trial_log_label(spec.label):
            scenario = with_perception(load_scenario(spec.scenario_path), spec.perception)
            config = campaign_config(spec.config_path, spec.overrides, spec.label)
            place = CampaignPlace(spec.terrain, spec.variant, spec.terrain_index, spec.variant_index)
            result = run_trial(scenario, config, spec.out_dir, seed=spec.seed, campaign=place)
    except Exception as err:  # a broken trial must not take the campaign down; it is reported
        logger.exception("trial %s failed", spec.label)
        return TrialOutcome(
            spec, False, "error", False, (), None, 0.0, time.perf_counter() - started, repr(err)
        )
    return TrialOutcome(
        spec,
        True,
        result.end_reason,
        result.success,
        result.failures,
        result.metrics_path,
        result.simulated_s,
        time.perf_counter() - started,
    )


def run_campaign(
    campaign: Campaign,
    out_dir: Path,
    *,
    workers: int | None = None,
    on_done: Callable[[TrialOutcome], None] | None = None,
) -> tuple[list[TrialOutcome], Path, Path]:
    """Run every trial; returns the outcomes and the Markdown and JSON summary paths.

    ``workers``: worker processes (0: one per core); None: the campaign file's ``workers``."""
    specs = campaign.trials(out_dir)
    others = other_recordings(out_dir, specs)
    if others:
        logger.warning("%s", others_sentence(out_dir, others))
    count = campaign.worker_count(workers)
    outcomes: list[TrialOutcome] = []
    if count <= 1:
        for spec in specs:
            outcome = run_one(spec)
            outcomes.append(outcome)
            if on_done is not None:
                on_done(outcome)
    else:
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=min(count, len(specs)), mp_context=context) as pool:
            futures: dict[Future[TrialOutcome], TrialSpec] = {pool.submit(run_one, s): s for s in specs}
            for future in as_completed(futures):
                try:
                    outcome = future.result()
                except BrokenProcessPool as err:
                    outcome = _lost(futures[future], err)
                outcomes.append(outcome)
                if on_done is not None:
                    on_done(outcome)
    order = {spec.label: index for index, spec in enumerate(specs)}
    outcomes.sort(key=lambda o: order[o.spec.label])
    rows = [_row(o) for o in outcomes]
    markdown, json_path = write_summary(campaign, rows, out_dir, others)
    return outcomes, markdown, json_path


def other_recordings(out_dir: Path, specs: list[TrialSpec]) -> list[str]:
    """The recordings already in ``out_dir`` that this campaign does not write (an earlier run's, with
    other seeds, terrains or variants), relative to it: its summary leaves them out, but
    ``rover logs report OUT`` reads every recording in the folder."""
    ours = {spec.out_dir / "trial.mcap" for spec in specs}
    if not out_dir.is_dir():
        return []
    return sorted(str(path.relative_to(out_dir)) for path in out_dir.rglob("*.mcap") if path not in ours)


def _lost(spec: TrialSpec, err: BrokenProcessPool) -> TrialOutcome:
    """A trial whose worker process died, or that was still pending when another worker died (the pool
    is then broken and runs nothing more): an error row, so the trials that finished are still summed up."""
    logger.error("trial %s lost: %s", spec.label, err)
    reason = (
        "a worker process died (killed, out of memory, or a crash outside Python) before this trial "
        "finished; the campaign's other unfinished trials were lost with it"
    )
    return TrialOutcome(spec, False, "error", False, (), None, 0.0, 0.0, reason)


def _row(outcome: TrialOutcome) -> dict[str, Any]:
    metrics: dict[str, Any] = {}
    if outcome.metrics_path is not None:
        metrics = json.loads(outcome.metrics_path.read_text(encoding="utf-8"))
    return {
        "terrain": outcome.spec.terrain,
        "variant": outcome.spec.variant,
        "seed": outcome.spec.seed,
        "ok": outcome.ok,
        "end_reason": outcome.end_reason,
        "success": outcome.success,
        "failures": list(outcome.failures),
        "error": outcome.error,
        "mcap": str(outcome.spec.out_dir / "trial.mcap") if outcome.ok else None,
        "simulated_s": outcome.simulated_s,
        "wall_s": outcome.wall_s,
        "metrics": metrics,
    }
