"""A lockstep trial keeps the collector off its start-up heap while the loop runs, and hands it back."""

from __future__ import annotations

import dataclasses
import gc
from pathlib import Path

from hil.scenario import load_scenario
from hil.trial import run_trial
from rover_cli.hil_commands import load_config

SMALL = Path(__file__).parents[1] / "data" / "small_rocky.toml"


def test_the_start_up_heap_is_frozen_during_the_loop_and_unfrozen_after(tmp_path):
    scenario = dataclasses.replace(load_scenario(SMALL), duration_s=2.0)
    # An in-process `rover run` earlier in this process (a parallel worker's test order) froze its own
    # start-up heap for good; the trial's unfreeze hands that back too. Start from none frozen.
    gc.unfreeze()
    frozen_before = gc.get_freeze_count()
    frozen_during: list[int] = []
    run_trial(
        scenario,
        load_config(None),
        tmp_path,
        telemetry=None,
        on_progress=lambda _share: frozen_during.append(gc.get_freeze_count()),
    )
    # The world, the stack and the modules were frozen: many more objects than before the trial.
    assert frozen_during and min(frozen_during) > frozen_before + 10_000
    # And returned to the collector afterwards, so a campaign worker's trials do not pile up.
    assert gc.get_freeze_count() == frozen_before
