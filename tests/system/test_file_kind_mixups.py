"""A scenario given where a rover config goes, or a rover config where a scenario goes, is named as that
mix-up, not as the first key the other kind of file does not have ("name: required key is missing",
"description: unknown key")."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.scenario import load_scenario
from logs.settings import ConfigError
from navigator.config import load_rover_config

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ["scenarios/default.toml", "scenarios/maze.toml", "scenarios/hills-1.toml"]
CONFIGS = ["configs/rover.toml", "configs/rover.example-hardware.toml"]


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_a_scenario_given_as_the_rover_config_is_named_as_one(scenario: str) -> None:
    with pytest.raises(ConfigError) as caught:
        load_rover_config(ROOT / scenario)
    assert caught.value.key == ""
    assert caught.value.problem == (
        "this is a scenario file (it has [terrain], [start] and [[goals]]), not a rover config: a rover "
        "config (configs/rover.toml lists every key) goes here"
    )


@pytest.mark.parametrize("config", CONFIGS)
def test_a_rover_config_given_as_the_scenario_is_named_as_one(config: str) -> None:
    with pytest.raises(ConfigError) as caught:
        load_scenario(ROOT / config)
    assert caught.value.key == ""
    assert caught.value.problem.startswith("this is a rover config (it has ["), caught.value.problem
    assert caught.value.problem.endswith(
        "), not a scenario: a scenario (scenarios/default.toml, docs/hil.md) goes here, "
        "the rover config after --config"
    ), caught.value.problem


def test_a_rover_config_of_its_map_alone_is_named_as_one(tmp_path: Path) -> None:
    # [map] is a rover config's table too; a config holding only it read as "name: required key is missing".
    config = tmp_path / "map-only.toml"
    config.write_text('[map]\nkind = "procedural"\nsize_m = [10.0, 10.0]\nresolution_m = 0.5\n')
    with pytest.raises(ConfigError) as caught:
        load_scenario(config)
    assert caught.value.problem.startswith("this is a rover config (it has [map])"), caught.value.problem
