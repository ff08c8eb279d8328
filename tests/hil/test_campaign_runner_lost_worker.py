"""A campaign whose worker process dies (killed, out of memory, a crash outside Python) keeps what ran; a
campaign run into a folder that holds another run's recordings says so.

`rover hil campaign` once ended in a ``BrokenProcessPool`` traceback when a worker was killed: no
summary.md or summary.json, not even for the trials that had finished. The pool here is a stand-in that
finishes some trials and breaks on one, as ``ProcessPoolExecutor`` does when a worker dies: that future
and every one still pending raise ``BrokenProcessPool``.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

import pytest

import hil.campaign_runner as campaign_runner
from hil.campaign import Campaign, Variant
from hil.campaign_runner import TrialOutcome, run_campaign

SEEDS = (1, 2, 3, 4)
DIES_AT_SEED = 3  # the worker running this trial is killed; seed 4 is still pending then


class _BreakingPool:
    """Runs the trials before ``dies_at``; from it on every future fails as a broken pool's do."""

    dies_at: int | None = DIES_AT_SEED

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.broken = False

    def __enter__(self) -> _BreakingPool:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def submit(self, fn: Callable[..., TrialOutcome], spec: Any) -> Future[TrialOutcome]:
        future: Future[TrialOutcome] = Future()
        self.broken = self.broken or spec.seed == self.dies_at
        if self.broken:
            future.set_exception(BrokenProcessPool("A process in the process pool was terminated abruptly"))
            return future
        spec.out_dir.mkdir(parents=True, exist_ok=True)
        metrics = spec.out_dir / "metrics.json"
        metrics.write_text(json.dumps({"route_accuracy_pct": 90.0 + spec.seed}), encoding="utf-8")
        future.set_result(TrialOutcome(spec, True, "arrived", True, (), metrics, 40.0, 1.0))
        return future


class _Pool(_BreakingPool):
    dies_at = None


CAMPAIGN = Campaign(
    "mini", "mini.toml", (("rocky", Path("rocky.toml")),), (Variant("v", {}),), SEEDS, None, 2
)


def test_a_dead_worker_is_an_error_row_and_the_summary_is_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(campaign_runner, "ProcessPoolExecutor", _BreakingPool)
    campaign = CAMPAIGN
    seen: list[TrialOutcome] = []
    outcomes, markdown, json_path = run_campaign(campaign, tmp_path, on_done=seen.append)
    assert [o.ok for o in outcomes] == [True, True, False, False]
    assert len(seen) == len(SEEDS)  # the progress heard of every trial, the lost ones too
    assert all("worker process" in o.error for o in outcomes if not o.ok)
    table2 = json.loads(json_path.read_text(encoding="utf-8"))["table2"]
    assert [row["metrics"].get("route_accuracy_pct") for row in table2] == [91.0, 92.0, None, None]
    text = markdown.read_text(encoding="utf-8")
    assert "| rocky | v | 3 | error: " in text and "BrokenProcessPool" not in text


def test_recordings_of_an_earlier_run_in_the_folder_are_named(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """The campaign run again into its --out with fewer seeds: summary.md said 1 trial, 100.0 % path
    accuracy, and `rover logs report OUT` 2 runs, 98.99 %, reading seed 2's trial.mcap of the earlier run,
    which nothing named."""
    monkeypatch.setattr(campaign_runner, "ProcessPoolExecutor", _Pool)
    earlier = tmp_path / "rocky" / "v" / "seed9" / "trial.mcap"
    earlier.parent.mkdir(parents=True)
    earlier.write_bytes(b"an earlier run's recording")
    rewritten = tmp_path / "rocky" / "v" / "seed1" / "trial.mcap"  # this run writes it again
    rewritten.parent.mkdir(parents=True)
    rewritten.write_bytes(b"")
    _outcomes, markdown, json_path = run_campaign(CAMPAIGN, tmp_path)
    where = str(Path("rocky") / "v" / "seed9" / "trial.mcap")
    text = " ".join(markdown.read_text(encoding="utf-8").split())
    assert f"also holds 1 recording this campaign did not write ({where})" in text
    assert json.loads(json_path.read_text(encoding="utf-8"))["other_recordings"] == [where]
    assert where in caplog.text
