"""`rover plan` reads and parses its map file once: the terrain, the rover's map and the start and goal all
come from that one parse (it used to parse a scenario up to three times), and what it prints is the plan
the map gives."""

import json
import tomllib
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hil.scenario import load_scenario
from navigator.config import PlannerConfig, load_rover_config
from navigator.plan_tools import load_map
from navigator.planner import Planner
from navigator.terrain import TerrainMap
from navigator.vehicle import VehicleParams
from rover_cli.main import main

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
CONFIG_WITH_MAP = '[map]\nkind = "procedural"\nsize_m = [10.0, 10.0]\nresolution_m = 0.5\n'


def _map_file(kind: str, tmp_path: Path) -> tuple[Path, TerrainMap, tuple[float, float], tuple[float, float]]:
    """The file ``rover plan`` is given, and the map and endpoints it should plan with (read beforehand)."""
    if kind == "scenario with obstacles":
        path = SCENARIOS / "default.toml"
        scenario = load_scenario(path)
        assert scenario.obstacles  # the branch that builds the rover's map from the whole scenario
        goal = scenario.goals[0]
        return path, scenario.believed_terrain, scenario.start_xy, (goal.x, goal.y)
    if kind == "terrain and endpoints":
        path = SCENARIOS / "hills-2.toml"
        plan_map = load_map(path, None)
        assert plan_map.start is not None and plan_map.goal is not None
        return path, plan_map.terrain, plan_map.start, plan_map.goal
    path = tmp_path / "rover.toml"
    path.write_text(CONFIG_WITH_MAP)
    terrain = load_rover_config(path).terrain
    assert terrain is not None
    return path, terrain, (1.0, 1.0), (8.0, 8.0)


KINDS = ["scenario with obstacles", "terrain and endpoints", "rover config with a map"]


@pytest.mark.parametrize("kind", KINDS)
def test_plan_reads_its_map_file_once_and_prints_that_maps_plan(
    kind: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    path, terrain, start, goal = _map_file(kind, tmp_path)
    options = [] if kind != "rover config with a map" else ["--start", "1,1", "--goal", "8,8"]
    expected = Planner.from_config(terrain, VehicleParams(), PlannerConfig()).plan(start, goal)

    reads: Counter[Path] = Counter()
    parses: list[str] = []
    read_text, loads = Path.read_text, tomllib.loads

    def counted_read_text(self: Path, *args: Any, **kwargs: Any) -> str:
        reads[self.resolve()] += 1
        return read_text(self, *args, **kwargs)

    def counted_loads(text: str, **kwargs: Any) -> dict[str, Any]:
        parses.append(text)
        return loads(text, **kwargs)

    monkeypatch.setattr(Path, "read_text", counted_read_text)
    monkeypatch.setattr(tomllib, "loads", counted_loads)
    assert main(["plan", str(path), "--json", *options]) == 0
    monkeypatch.undo()

    assert reads[path.resolve()] == 1
    assert len(parses) == 1  # no --config: the map file is the only TOML the command reads
    figures = json.loads(capsys.readouterr().out)
    assert figures["cost"] == expected.cost and figures["expanded"] == expected.expanded
    assert figures["path"] == np.asarray(expected.points).tolist()
