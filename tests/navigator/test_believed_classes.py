"""A rover config's ``[terrain_classes.<name>]`` is what the onboard stack plans with: the class costs, the
climb limits, in guidance as in ``rover plan --config``."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from logs.settings import parse_toml
from logs.sink import NullSink
from navigator.config import RoverConfig, rover_config_from_table
from navigator.planner import Planner
from navigator.route_guidance import RouteGuidance
from navigator.terrain import TerrainMap
from navigator.terrain_classes import SANDY, TERRAIN_CLASSES
from rover_cli.main import main

SIZE, RES = 48, 0.25
CENTRE = (SIZE // 2, SIZE // 2)


def config_of(text: str) -> RoverConfig:
    return rover_config_from_table(parse_toml(text, "rover.toml"))


def sandy_map(grade: float = 0.0) -> TerrainMap:
    xs = (np.arange(SIZE) + 0.5) * RES
    elevation = np.tile(grade * xs, (SIZE, 1))
    return TerrainMap(elevation, np.full((SIZE, SIZE), SANDY, np.uint8), np.zeros((SIZE, SIZE), bool), RES)


def planner_for(config: RoverConfig, terrain: TerrainMap) -> Planner:
    return Planner.from_config(terrain, config.vehicle, config.planner, classes=config.classes)


def guidance_planner(config: RoverConfig, terrain: TerrainMap) -> Planner:
    """The planner the onboard stack builds (``RouteGuidance``, as ``OnboardStack`` makes it)."""
    return RouteGuidance(config, terrain, NullSink(), lambda *_: None).planner


@pytest.mark.parametrize("build", [planner_for, guidance_planner])
def test_the_configs_cost_factor_is_the_planners_cost_of_sand(
    build: Callable[[RoverConfig, TerrainMap], Planner],
) -> None:
    default = build(config_of(""), sandy_map()).cost_grid[CENTRE]
    believed = build(config_of("[terrain_classes.sandy]\ncost_factor = 3.5\n"), sandy_map()).cost_grid[CENTRE]
    # Level, smooth, far from any obstacle and the edge: the cost is the class factor alone.
    assert (default, believed) == (TERRAIN_CLASSES[SANDY].cost_factor, 3.5)


@pytest.mark.parametrize("build", [planner_for, guidance_planner])
def test_the_configs_friction_sets_the_planners_climb_limit_on_sand(
    build: Callable[[RoverConfig, TerrainMap], Planner],
) -> None:
    # Climb limit atan(mu - crr) less 3 deg (docs/planning.md): 12.6 deg with the table's sand (mu 0.4),
    # 7.2 deg if the rover believes mu 0.3; the slope is 11.3 deg.
    grade = 0.2
    assert math.atan(0.3 - 0.12) - math.radians(3.0) < math.atan(grade)
    assert math.atan(grade) < math.atan(0.4 - 0.12) - math.radians(3.0)
    assert np.isfinite(build(config_of(""), sandy_map(grade)).cost_grid[CENTRE])
    slippery = config_of("[terrain_classes.sandy]\nfriction_mu = 0.3\n")
    assert np.isinf(build(slippery, sandy_map(grade)).cost_grid[CENTRE])


def test_rover_plan_plans_with_the_configs_beliefs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = Path(__file__).resolve().parents[2] / "scenarios" / "sandy.toml"
    dear = tmp_path / "dear-sand.toml"
    dear.write_text("[terrain_classes.sandy]\ncost_factor = 4.0\n", encoding="utf-8")
    costs = []
    for extra in ([], ["--config", str(dear)]):
        assert main(["plan", str(scenario), "--json", *extra]) == 0
        costs.append(json.loads(capsys.readouterr().out)["cost"])
    # All sand: every cell's class term doubles, so the path costs nearly twice as much.
    assert costs[1] > 1.8 * costs[0]
