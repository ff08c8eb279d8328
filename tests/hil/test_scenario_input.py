"""Scenarios that cannot run as meant are refused at load: a start or goal inside an obstacle, bad tags,
an elevation layer that is not numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hil.scenario import load_scenario
from logs.settings import ConfigError
from rover_cli.main import main

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "small_rocky.toml"  # rock at (6.5, 4.5), r 0.8


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("old", "new", "key", "distance"),
    [
        ("xy = [2.0, 2.0]", "xy = [6.5, 4.5]", "start.xy", "0.00 m"),
        ("xy = [2.0, 2.0]", "xy = [6.9, 4.9]", "start.xy", "0.57 m"),
        ("xy = [11.5, 7.5]", "xy = [6.0, 4.5]", "goals[0].xy", "0.50 m"),
    ],
)
def test_a_start_or_goal_inside_an_obstacle_names_it_and_the_distance(
    tmp_path: Path, old: str, new: str, key: str, distance: str
) -> None:
    text = SCENARIO.read_text()
    assert old in text
    with pytest.raises(ConfigError) as caught:
        load_scenario(_write(tmp_path, text.replace(old, new)))
    assert caught.value.key == key
    assert "'rock'" in caught.value.problem and distance in caught.value.problem


def test_an_unknown_obstacle_counts_too(tmp_path: Path) -> None:
    text = (
        SCENARIO.read_text()
        + '\n[[obstacles]]\nid = "hidden"\nxy = [11.0, 7.0]\nradius_m = 1.0\nknown = false\n'
    )
    with pytest.raises(ConfigError) as caught:
        load_scenario(_write(tmp_path, text))
    assert caught.value.key == "goals[0].xy" and "'hidden'" in caught.value.problem


def test_a_start_in_a_cell_the_disc_covers_is_refused(tmp_path: Path) -> None:
    # 0.89 m from the centre, past the 0.8 m radius, but in a 0.25 m cell whose centre is 0.73 m from it:
    # the obstacle layer marks that cell, so the rover would start on an obstacle.
    text = SCENARIO.read_text().replace("xy = [2.0, 2.0]", "xy = [7.24, 4.99]")
    with pytest.raises(ConfigError) as caught:
        load_scenario(_write(tmp_path, text))
    assert caught.value.key == "start.xy" and "'rock'" in caught.value.problem
    assert "0.89 m" in caught.value.problem


def test_a_start_on_the_maps_own_obstacle_layer_is_refused(tmp_path: Path) -> None:
    text = (
        'name = "m"\n[terrain]\nkind = "maze"\ncell_size_m = 1.0\n'
        "matrix = [[2, 2, 2], [2, 1, 2], [2, 2, 2]]\n"
        "[start]\nxy = [1.5, 1.5]\n[[goals]]\nxy = [0.5, 0.5]\n"
    )
    with pytest.raises(ConfigError) as caught:
        load_scenario(_write(tmp_path, text))
    assert caught.value.key == "start.xy" and "obstacle layer" in caught.value.problem


def test_the_cli_refuses_a_start_inside_an_obstacle_without_writing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = _write(tmp_path, SCENARIO.read_text().replace("xy = [2.0, 2.0]", "xy = [6.5, 4.5]"))
    out = tmp_path / "out"
    assert main(["hil", "trial", str(bad), "--out", str(out), "--no-telemetry"]) == 2
    assert "start.xy" in capsys.readouterr().out
    assert not out.exists()


@pytest.mark.parametrize("tags", ['"sandy"', "[1, 2]", '["ok", 3]', "{ a = 1 }"])
def test_tags_must_be_a_list_of_strings(tmp_path: Path, tags: str) -> None:
    text = SCENARIO.read_text().replace("seed = 3", f"seed = 3\ntags = {tags}", 1)
    with pytest.raises(ConfigError) as caught:
        load_scenario(_write(tmp_path, text))
    assert caught.value.key == "tags"


def test_tags_as_a_list_are_kept(tmp_path: Path) -> None:
    text = SCENARIO.read_text().replace("seed = 3", 'seed = 3\ntags = ["rocky", "small"]', 1)
    assert load_scenario(_write(tmp_path, text)).tags == ("rocky", "small")


def _npy_scenario(tmp_path: Path, layer: np.ndarray) -> Path:
    np.save(tmp_path / "e.npy", layer)
    return _write(
        tmp_path,
        'name = "n"\n[terrain]\nkind = "npy"\nresolution_m = 1.0\nelevation = "e.npy"\n'
        "[start]\nxy = [0.5, 0.5]\n[[goals]]\nxy = [2.5, 2.5]\n",
    )


@pytest.mark.parametrize(
    ("layer", "problem"),
    [
        (np.full((3, 3), "1.0"), "dtype"),  # numbers as text: numpy would convert them without a word
        (np.full((3, 3), "high"), "dtype"),
        (np.ones((3, 3), dtype=bool), "dtype"),
        (np.ones((3, 3), dtype=complex), "dtype"),
        (np.where(np.eye(3) > 0, np.nan, 0.0), "non-finite"),
        (np.where(np.eye(3) > 0, np.inf, 0.0), "non-finite"),
    ],
)
def test_an_elevation_layer_that_is_not_finite_numbers_is_refused(
    tmp_path: Path, layer: np.ndarray, problem: str
) -> None:
    with pytest.raises(ConfigError) as caught:
        load_scenario(_npy_scenario(tmp_path, layer))
    assert caught.value.key == "terrain.elevation"
    assert problem in caught.value.problem


@pytest.mark.parametrize(
    ("key", "layer"), [("classes", np.full((3, 3), "firm")), ("obstacles", np.full((3, 3), "x"))]
)
def test_class_and_obstacle_layers_of_text_name_their_key(
    tmp_path: Path, key: str, layer: np.ndarray
) -> None:
    np.save(tmp_path / "l.npy", layer)
    path = _npy_scenario(tmp_path, np.zeros((3, 3)))
    path.write_text(path.read_text().replace('elevation = "e.npy"', f'elevation = "e.npy"\n{key} = "l.npy"'))
    with pytest.raises(ConfigError) as caught:
        load_scenario(path)
    assert caught.value.key == f"terrain.{key}" and "dtype" in caught.value.problem


def test_a_file_that_is_not_npy_gets_one_sentence(tmp_path: Path) -> None:
    path = _npy_scenario(tmp_path, np.zeros((3, 3)))
    (tmp_path / "e.npy").write_text("hello")
    with pytest.raises(ConfigError) as caught:
        load_scenario(path)
    assert caught.value.key == "terrain.elevation"
    assert caught.value.problem.count("e.npy") == 1 and caught.value.problem.count(".npy array") == 1


@pytest.mark.parametrize("start_s", [4700.0, 45.0])
def test_a_moving_obstacle_that_would_start_after_the_trial_is_refused(
    tmp_path: Path, start_s: float
) -> None:
    # start_s in milliseconds (4.7 s written 4700): the cart would stand at its first waypoint for the whole
    # trial, a static obstacle, and the trial pass having tested nothing that moves. A fault is refused so.
    text = SCENARIO.read_text()
    assert "duration_s = 45.0" in text
    mover = (
        '\n[[moving_obstacles]]\nid = "cart"\nradius_m = 0.4\nspeed_mps = 0.8\n'
        f"waypoints = [[9.0, 1.0], [9.0, 8.0]]\nstart_s = {start_s}\n"
    )
    with pytest.raises(ConfigError) as caught:
        load_scenario(_write(tmp_path, text + mover))
    assert caught.value.key == "moving_obstacles[0].start_s"
    assert caught.value.problem == (
        f"{start_s:g} s is not before the scenario's duration_s 45 s: the obstacle would never move"
    )


def test_a_fault_of_zero_seconds_is_refused(tmp_path: Path) -> None:
    # Active from start_s until start_s: it never happens, and the trial would pass having broken nothing.
    fault = '\n[[faults]]\ntarget = "gps"\nkind = "off"\nstart_s = 5.0\nduration_s = 0.0\n'
    with pytest.raises(ConfigError) as caught:
        load_scenario(_write(tmp_path, SCENARIO.read_text() + fault))
    assert caught.value.key == "faults[0].duration_s"
    assert "a fault of 0 s never happens" in caught.value.problem
