"""A scenario's ``[terrain_classes.<name>]`` is the ground the simulated rover drives on; a rover config's is
what the planner believes; each trial's recording keeps both, and the real-time peer hands the config's to
``rover run``."""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pytest

from hil.campaign import campaign_config, campaign_from_table
from hil.dynamics import RoverDynamics
from hil.peer_files import write_peer_files
from hil.trial import write_header
from logs.reader import read_metadata
from logs.recorder import McapRecorder
from logs.settings import ConfigError, parse_toml
from navigator.config import load_rover_config, rover_config_from_table
from navigator.terrain import TerrainMap
from navigator.terrain_classes import ROCKY, SANDY, TERRAIN_CLASSES
from navigator.vehicle import VehicleParams
from tests.hil.world_harness import run_world, scenario_with
from tests.logs.small_scenario import SMALL_SCENARIO, load_text

PARAMS = VehicleParams()
DT = 0.01


def sandy_plane(grade: float) -> TerrainMap:
    size, res = (80, 80), 0.25
    xs = (np.arange(size[1]) + 0.5) * res
    elevation = np.tile(grade * xs, (size[0], 1))
    return TerrainMap(elevation, np.full(size, SANDY, np.uint8), np.zeros(size, bool), res)


def climbs(classes: dict, grade: float) -> bool:
    """Whether the rover, all wheels at 1 m/s for 3 s, gets up a sandy slope of this grade (facing up it)."""
    body = RoverDynamics(sandy_plane(grade), PARAMS, classes, x=10.0, y=10.0, yaw=0.0)
    for _ in range(300):
        body.step(DT, [1.0] * 6, 24.0)
    return body.x > 10.5


def test_a_scenarios_slippery_sand_stops_a_climb_the_tables_sand_makes() -> None:
    scenario = load_text(SMALL_SCENARIO + "[terrain_classes.sandy]\nfriction_mu = 0.25\n")
    table, world = TERRAIN_CLASSES[SANDY], scenario.classes[SANDY]
    # The climb limit tan(theta) = mu - crr (docs/physics.md): 0.28 with the table's sand, 0.13 with this.
    grade = 0.20
    assert world.friction_mu - world.rolling_resistance < grade < table.friction_mu - table.rolling_resistance
    assert climbs(TERRAIN_CLASSES, grade)
    assert not climbs(scenario.classes, grade)
    # Below the retuned limit the retuned sand still climbs: the limit moved, the law did not.
    assert climbs(scenario.classes, 0.13 - 0.05)


def test_the_simulated_world_drives_on_the_scenarios_classes() -> None:
    # small_rocky.toml is all rock: grip for a tenth of g less its resistance leaves the rover crawling.
    table = run_world(seconds=3.0)
    slippery = run_world(
        "[terrain_classes.rocky]\nfriction_mu = 0.1\nrolling_resistance = 0.08\n", seconds=3.0
    )
    assert slippery.scenario.classes[ROCKY].friction_mu == 0.1

    def moved(run):
        return math.dist((run.world.body.x, run.world.body.y), run.scenario.start_xy)

    assert moved(table) > 1.2
    assert moved(slippery) < 0.5 * moved(table)


def recorded_metadata(scenario_extra: str, overrides: dict) -> dict[str, dict[str, str]]:
    scenario = scenario_with(scenario_extra)
    config = campaign_config(None, overrides, "test")
    stream = io.BytesIO()
    with McapRecorder(stream) as recorder:
        write_header(recorder, scenario, config, seed=1)
    return read_metadata(io.BytesIO(stream.getvalue()))


def test_the_recording_keeps_what_the_world_was_and_what_the_planner_believed() -> None:
    metadata = recorded_metadata(
        "[terrain_classes.sandy]\nfriction_mu = 0.25\n",
        {"terrain_classes": {"sandy": {"friction_mu": 0.4, "cost_factor": 3.0}}},
    )
    assert metadata["scenario"]["terrain_classes.sandy.friction_mu"] == "0.25"
    assert metadata["config"]["terrain_classes.sandy.friction_mu"] == "0.4"
    assert metadata["config"]["terrain_classes.sandy.cost_factor"] == "3.0"


def test_a_trial_without_tables_records_no_class_keys() -> None:
    metadata = recorded_metadata("", {})
    assert not [key for record in metadata.values() for key in record if "terrain_classes" in key]


def test_a_campaign_variant_sets_what_the_planner_believes_and_is_named_when_wrong() -> None:
    config = campaign_config(None, {"terrain_classes": {"sandy": {"friction_mu": 0.4}}}, "v")
    assert config.classes[SANDY].friction_mu == 0.4
    campaign = Path(__file__).resolve().parents[2] / "campaigns" / "paper.toml"
    variant = '[[variants]]\nname = "slippery-belief"\n[variants.overrides.terrain_classes.sandy]\n'
    text = f"{campaign.read_text(encoding='utf-8')}\n{variant}friction_mu = -1.0\n"
    with pytest.raises(ConfigError) as caught:
        campaign_from_table(parse_toml(text, "camp.toml"), campaign.parent)
    assert caught.value.key.endswith("overrides.terrain_classes.sandy.friction_mu")


def test_the_peer_hands_the_configs_beliefs_to_rover_run(tmp_path: Path) -> None:
    scenario = scenario_with("[terrain_classes.sandy]\nfriction_mu = 0.25\n")
    config = rover_config_from_table(
        parse_toml("[terrain_classes.sandy]\nfriction_mu = 0.4\ncost_factor = 3.0\n", "rover.toml")
    )
    written = load_rover_config(write_peer_files(tmp_path, scenario, config, 14550))
    assert written.terrain_classes == config.terrain_classes
    assert written.classes[SANDY].friction_mu == 0.4  # the belief, not the scenario's world
