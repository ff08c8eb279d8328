"""`rover plan`: figures as JSON, a PNG, and an exported edge-cost model an independent solver agrees with."""

import json
from pathlib import Path

import numpy as np
import pytest

from navigator.config import HEURISTIC_WEIGHT_RANGE
from navigator.plan_tools import load_map
from navigator.planner import Planner
from navigator.vehicle import VehicleParams
from rover_cli.main import main
from tests.navigator.test_direction_and_modes import _dijkstra_cost

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "hills-2.toml"


def test_plan_json_png_and_exported_costs_agree_with_dijkstra(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    export = tmp_path / "costs.npz"
    png = tmp_path / "path.png"
    code = main([
        "plan", str(SCENARIO), "--start", "3,12", "--goal", "25,5", "--json",
        "--png", str(png), "--export-costs", str(export),
    ])  # fmt: skip
    assert code == 0
    figures = json.loads(capsys.readouterr().out)
    assert figures["expanded"] > 0 and figures["length_m"] > 22.0 and png.stat().st_size > 1000
    data = np.load(export)
    start, goal = tuple(data["start"]), tuple(data["goal"])
    expected = _dijkstra_cost(data["cost"], data["factors"], start, goal)
    assert float(data["path_cost"]) == pytest.approx(expected, rel=1e-9)
    assert figures["cost"] == pytest.approx(expected * float(data["resolution_m"]), rel=1e-9)


def test_plan_reports_an_off_map_goal(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", str(SCENARIO), "--start", "3,12", "--goal", "300,12", "--json"]) == 2
    printed = capsys.readouterr()
    assert "off the map" in printed.err
    assert printed.out == ""  # a script reading the JSON on stdout gets nothing, not an error sentence


@pytest.mark.parametrize("option", ["--png", "--export-costs"])
def test_plan_names_an_output_it_cannot_write(
    option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "no-such-dir" / "out.file"
    assert main(["plan", str(SCENARIO), "--start", "3,12", "--goal", "25,5", option, str(out)]) == 2
    printed = capsys.readouterr()
    assert "cannot write" in printed.err and str(out) in printed.err
    assert "cannot write" not in printed.out


def test_plan_json_gives_the_path_in_metres(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", str(SCENARIO), "--start", "3,12", "--goal", "25,5", "--json"]) == 0
    figures = json.loads(capsys.readouterr().out)
    path = np.array(figures["path"])
    assert path.shape == (figures["points"], 2)
    assert np.linalg.norm(path[0] - (3.0, 12.0)) < 0.25 and np.linalg.norm(path[-1] - (25.0, 5.0)) < 0.25
    length = float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))
    assert length == pytest.approx(figures["length_m"], rel=1e-6)
    assert {"cost", "length_m", "expanded", "time_ms", "heuristic", "cost_mode", "points"} <= figures.keys()


def test_plan_takes_the_scenarios_own_start_and_goal(capsys: pytest.CaptureFixture[str]) -> None:
    # hills-2.toml: [start] xy = [3, 12], first [[goals]] xy = [47, 12]; --goal given overrides its goal.
    assert main(["plan", str(SCENARIO), "--json"]) == 0
    path = np.array(json.loads(capsys.readouterr().out)["path"])
    assert np.linalg.norm(path[0] - (3.0, 12.0)) < 0.25 and np.linalg.norm(path[-1] - (47.0, 12.0)) < 0.25
    assert main(["plan", str(SCENARIO), "--goal", "25,5", "--json"]) == 0
    path = np.array(json.loads(capsys.readouterr().out)["path"])
    assert np.linalg.norm(path[0] - (3.0, 12.0)) < 0.25 and np.linalg.norm(path[-1] - (25.0, 5.0)) < 0.25


def test_plan_names_the_missing_endpoint_of_a_bare_map(capsys: pytest.CaptureFixture[str]) -> None:
    elevation = SCENARIO.with_name("hills-2.elevation.npy")  # a bare layer: no [start] nor [[goals]]
    assert main(["plan", str(elevation), "--resolution-m", "0.25", "--start", "3,12"]) == 2
    printed = capsys.readouterr()
    assert "no --goal given" in printed.err and "[[goals]] xy" in printed.err and printed.out == ""


def test_plan_refuses_a_resolution_for_a_map_that_sets_its_own(capsys: pytest.CaptureFixture[str]) -> None:
    # It used to be ignored silently: the plan ran at the scenario's 0.25 m, not the 1 m asked for.
    assert main(["plan", str(SCENARIO), "--resolution-m", "1"]) == 2
    printed = capsys.readouterr()
    assert "--resolution-m" in printed.err and str(SCENARIO) in printed.err and printed.out == ""


def test_plan_starts_from_a_clearance_band_as_the_rover_does(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # (7.5, 3.3) is in the maze's corridor but within the footprint's clearance of its southern wall: the
    # rover's planner escapes to the nearest free cell; `rover plan` used to refuse it as a lethal start.
    maze = SCENARIO.with_name("maze.toml")
    export = tmp_path / "costs.npz"
    code = main(["plan", str(maze), "--start", "7.5,3.3", "--json", "--export-costs", str(export)])
    assert code == 0
    figures = json.loads(capsys.readouterr().out)
    assert figures["path"][0] == [7.5, 3.3]
    data = np.load(export)
    assert np.isinf(data["cost"][13, 30])  # the cell holding (7.5, 3.3) at 0.25 m: lethal (clearance)
    start, goal = tuple(data["start"]), tuple(data["goal"])
    assert np.isfinite(data["cost"][start]) and tuple(data["path"][0]) == start
    expected = _dijkstra_cost(data["cost"], data["factors"], start, goal)
    assert float(data["path_cost"]) == pytest.approx(expected, rel=1e-9)


def _json_plan(capsys: pytest.CaptureFixture[str], *options: str) -> dict:
    assert main(["plan", str(SCENARIO), "--start", "3,12", "--goal", "25,5", "--json", *options]) == 0
    return dict(json.loads(capsys.readouterr().out))


def test_plan_takes_the_vehicle_and_planner_settings_from_a_config_and_options_override_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "rover.toml"
    config.write_text(
        "[vehicle]\nfootprint_width_m = 0.8\n"
        '[planner]\ncost_mode = "classical"\nheuristic_weight = 2.0\ninflation_m = 0.3\n'
    )
    terrain = load_map(SCENARIO, None).terrain
    wide = VehicleParams(footprint_width_m=0.8)
    built_in = _json_plan(capsys)
    from_config = _json_plan(capsys, "--config", str(config))
    expected = Planner(terrain, wide, cost_mode="classical", heuristic_weight=2.0, inflation_m=0.3).plan(
        (3.0, 12.0), (25.0, 5.0)
    )
    assert (from_config["cost_mode"], from_config["heuristic_weight"]) == ("classical", 2.0)
    assert from_config["cost"] == pytest.approx(expected.cost)
    assert from_config["path"] == expected.points.tolist()
    assert from_config["cost"] != pytest.approx(built_in["cost"])
    # Options given on the command line win over the config; the rest of the config still holds.
    overridden = _json_plan(capsys, "--config", str(config), "--cost-mode", "terrain", "--weight", "1")
    expected = Planner(terrain, wide, inflation_m=0.3).plan((3.0, 12.0), (25.0, 5.0))
    assert (overridden["cost_mode"], overridden["heuristic_weight"]) == ("terrain", 1.0)
    assert overridden["cost"] == pytest.approx(expected.cost)
    assert overridden["path"] == expected.points.tolist()


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("[planner]\nheuristic_weight = 0.5\n", "planner.heuristic_weight"),
        ('[planner]\nheuristic = "dijkstra"\n', "planner.heuristic"),
        ("[vehicle]\nmass_kg = -1\n", "vehicle.mass_kg"),
    ],
)
def test_plan_refuses_a_bad_config_naming_the_file_and_key(
    text: str, key: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "rover.toml"
    config.write_text(text)
    assert main(["plan", str(SCENARIO), "--config", str(config), "--json"]) == 2
    printed = capsys.readouterr()
    assert f"{config}: {key}" in printed.err and printed.out == ""


@pytest.mark.parametrize("weight", ["0.5", "0", "10.5", "nan", "heavy"])
def test_plan_refuses_a_weight_the_config_would_refuse(
    weight: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exited:
        main(["plan", str(SCENARIO), "--weight", weight])
    assert exited.value.code == 2
    low, high = HEURISTIC_WEIGHT_RANGE
    assert "argument --weight: " in (err := capsys.readouterr().err) and f"{low:g} to {high:g}" in err
    assert main(["plan", str(SCENARIO), "--start", "3,12", "--goal", "25,5", "--weight", f"{high:g}"]) == 0


def test_plan_on_a_scenario_plans_on_the_rovers_map_with_its_known_obstacles(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """As a trial's rover plans: the scenario's known obstacles are on its map from the start (they used to
    be left out, and `rover plan scenarios/default.toml --goal 9,7` planned into boulder-1)."""
    from hil.scenario import load_scenario

    default = SCENARIO.with_name("default.toml")
    assert main(["plan", str(default), "--goal", "9,7"]) == 2
    assert "goal cell" in capsys.readouterr().err
    assert main(["plan", str(default), "--json"]) == 0
    path = np.array(json.loads(capsys.readouterr().out)["path"])
    obstacles = load_scenario(default).obstacles
    assert obstacles and all(o.known for o in obstacles)
    for obstacle in obstacles:
        clearance = np.min(np.linalg.norm(path - (obstacle.x, obstacle.y), axis=1)) - obstacle.radius_m
        assert clearance > 0.0, obstacle.id
    # An obstacle the rover does not know (known = false) is not on its map: it finds it on the drive.
    unknown = tmp_path / "unknown.toml"
    unknown.write_text(default.read_text().replace("radius_m = 1.0\n", "radius_m = 1.0\nknown = false\n", 1))
    assert main(["plan", str(unknown), "--goal", "9,7"]) == 0


def test_plan_names_a_rover_config_without_a_map_given_as_the_map(capsys: pytest.CaptureFixture[str]) -> None:
    config = SCENARIO.parents[1] / "configs" / "rover.toml"  # no [map]: a trial's rover gets the scenario's
    assert main(["plan", str(config)]) == 2
    assert "this is a rover config" in capsys.readouterr().err


def test_plan_on_a_rover_config_plans_on_its_map_as_rover_run_does(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "rover.toml"
    config.write_text('[map]\nkind = "procedural"\nsize_m = [10.0, 10.0]\nresolution_m = 0.5\n')
    assert main(["plan", str(config), "--start", "1,1", "--goal", "8,8", "--json"]) == 0
    path = np.array(json.loads(capsys.readouterr().out)["path"])
    assert np.linalg.norm(path[-1] - (8.0, 8.0)) < 0.5
    assert main(["plan", str(config), "--start", "1,1"]) == 2  # a config names no goal
    assert "no --goal given" in capsys.readouterr().err
