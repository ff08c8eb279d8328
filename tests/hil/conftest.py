"""Fixtures shared by tests/hil: the short lockstep trials the replay tests replay, run once a session."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.scenario import load_scenario
from hil.trial import run_trial
from tests.hil.replay_trials import DATA, config_of


@pytest.fixture(scope="session")
def trials(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A trial perceiving obstacles as objects (small_rocky), one through a lidar's scans (hidden_rock), one
    with faults, a moving cart and the simulator's log lines (sandy_cart_glitch), and 6 s of small_rocky
    with two CAN bus-offs, the second still on at the end (small_rocky_bus_off)."""
    out = tmp_path_factory.mktemp("replay-trials")
    return {
        name: run_trial(load_scenario(DATA / f"{name}.toml"), config_of(), out / name).mcap_path
        for name in ("small_rocky", "hidden_rock", "sandy_cart_glitch", "small_rocky_bus_off")
    }
