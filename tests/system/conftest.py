from __future__ import annotations

from pathlib import Path

import pytest

from hil.scenario import Scenario, load_scenario
from hil.trial import TrialResult, run_trial
from logs.settings import parse_toml
from navigator.config import RoverConfig, rover_config_from_table

DATA = Path(__file__).resolve().parents[1] / "data"


@pytest.fixture(scope="session")
def small_scenario() -> Scenario:
    return load_scenario(DATA / "small_rocky.toml")


@pytest.fixture(scope="session")
def default_config() -> RoverConfig:
    return rover_config_from_table(parse_toml("", "<defaults>"))


@pytest.fixture(scope="session")
def small_trial(
    small_scenario: Scenario, default_config: RoverConfig, tmp_path_factory: pytest.TempPathFactory
) -> TrialResult:
    return run_trial(small_scenario, default_config, tmp_path_factory.mktemp("trial-a"))


@pytest.fixture(scope="session")
def cart_lane_trial(default_config: RoverConfig, tmp_path_factory: pytest.TempPathFactory) -> TrialResult:
    """``cart_in_lane.toml``: a crossing cart catches the rover with its nose in its lane."""
    return run_trial(
        load_scenario(DATA / "cart_in_lane.toml"), default_config, tmp_path_factory.mktemp("lane")
    )
