"""A typo'd key anywhere in a scenario, a campaign or a rover config is named first, as an unknown key with
the key it is one slip from: ``obstacles[1].raduis_m: unknown key (did you mean 'radius_m'? ...)``, not
``obstacles[1].radius_m: required key is missing``, which never names what the user wrote.

Every key of every table of the shipped files (and of test scenarios with the tables they lack: moving
obstacles, faults, rangefinders, [success]) is misspelt in turn, two neighbouring letters swapped."""

from __future__ import annotations

import copy
import tomllib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from hil.campaign import campaign_from_table
from hil.scenario import scenario_from_table
from logs.settings import ConfigError, Table
from navigator.config import rover_config_from_table

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = [
    "scenarios/default.toml",  # procedural terrain, obstacles
    "scenarios/maze.toml",  # the maze matrix
    "scenarios/hills-1.toml",  # .npy layers
    "scenarios/carts.toml",  # moving obstacles, [sensors], [success]
    "tests/data/sandy_cart_glitch.toml",  # faults
    "tests/data/png_walls.toml",  # image layers
    "tests/data/small_rocky_bus_off.toml",
]
CAMPAIGNS = ["campaigns/paper.toml", "campaigns/perception.toml"]
CONFIGS = ["configs/rover.toml", "configs/rover.example-hardware.toml"]

Load = Callable[[Table, Path], object]


def _load_scenario(root: Table, base: Path) -> object:
    return scenario_from_table(root, "", base)


def _load_config(root: Table, base: Path) -> object:
    return rover_config_from_table(root, base)


# A scenario with the rangefinder ring given sensor by sensor, so [sensors] rangefinders is misspelt too.
RANGEFINDERS = {
    "perception": "rangefinders",
    "rangefinders": [{"yaw_deg": 0.0, "forward_m": 0.3, "left_m": 0.0}, {"yaw_deg": 90.0}],
}


def _files() -> Iterator[tuple[str, Load, dict[str, Any]]]:
    for name in SCENARIOS:
        yield name, _load_scenario, _data(name)
    with_ring = _data("scenarios/default.toml")
    with_ring["sensors"] = copy.deepcopy(RANGEFINDERS)
    yield "scenarios/default.toml with rangefinders", _load_scenario, with_ring
    for name in CAMPAIGNS:
        yield name, campaign_from_table, _data(name)
    for name in CONFIGS:
        yield name, _load_config, _data(name)


def _data(name: str) -> dict[str, Any]:
    return tomllib.loads((ROOT / name).read_text(encoding="utf-8"))


def _keys(table: dict[str, Any], prefix: str = "") -> Iterator[tuple[tuple[str | int, ...], str]]:
    """(where the key is, as a path of keys and indexes; the dotted path Table names it by) for every key
    of every table and array of tables."""
    for key, value in table.items():
        dotted = f"{prefix}.{key}" if prefix else key
        yield (key,), dotted
        if isinstance(value, dict):
            for inner, inner_dotted in _keys(value, dotted):
                yield (key, *inner), inner_dotted
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for index, entry in enumerate(value):
                for inner, inner_dotted in _keys(entry, f"{dotted}[{index}]"):
                    yield (key, index, *inner), inner_dotted


def _misspelt(key: str) -> str:
    """``key`` with its first two different neighbouring letters swapped (``radius_m`` -> ``arduis_m``)."""
    index = next(i for i in range(len(key) - 1) if key[i] != key[i + 1])
    return key[:index] + key[index + 1] + key[index] + key[index + 2 :]


CASES = [
    pytest.param(name, load, data, where, dotted, id=f"{name}:{dotted}")
    for name, load, data in _files()
    for where, dotted in _keys(data)
    # A variant's overrides are rover-config keys, checked as the config's (under variants[i].overrides).
    if not dotted.endswith(".overrides")
    # Grey levels mapped to classes: numbers, not names (a number not in the image is no error).
    and ".class_values." not in dotted
]


def test_every_file_and_table_is_covered() -> None:
    dotted_keys = [dotted for _, _, data in _files() for _, dotted in _keys(data)]
    tables = {dotted.rsplit(".", 1)[0].split("[")[0] for dotted in dotted_keys}
    for table in ("obstacles", "moving_obstacles", "sensors.rangefinders", "faults", "success", "goals"):
        assert table in tables, sorted(tables)
    for table in ("terrain", "start", "terrains", "variants", "vehicle", "planner", "map", "mavlink"):
        assert table in tables, sorted(tables)


@pytest.mark.parametrize(("name", "load", "data", "where", "dotted"), CASES)
def test_a_misspelt_key_is_named_as_unknown_with_the_key_meant(
    name: str, load: Load, data: dict[str, Any], where: tuple[str | int, ...], dotted: str
) -> None:
    assert load(Table(copy.deepcopy(data), name, ""), (ROOT / name.split()[0]).parent) is not None
    broken = copy.deepcopy(data)
    table: Any = broken
    for step in where[:-1]:
        table = table[step]
    key = str(where[-1])
    table[_misspelt(key)] = table.pop(key)
    with pytest.raises(ConfigError) as caught:
        load(Table(broken, name, ""), (ROOT / name.split()[0]).parent)
    typo = dotted[: len(dotted) - len(key)] + _misspelt(key)
    assert caught.value.key == typo, str(caught.value)
    # "unknown key", or for a [zenoh.rates] topic "unknown topic"; the key meant first, then the rest.
    assert caught.value.problem.startswith("unknown "), str(caught.value)
    assert f"(did you mean {key!r}? " in caught.value.problem, str(caught.value)


def test_an_obstacles_misspelt_radius_is_named_in_the_file(tmp_path: Path) -> None:
    # The review's case, end to end through the CLI's loader.
    from hil.scenario import load_scenario

    text = (ROOT / "scenarios/default.toml").read_text(encoding="utf-8")
    path = tmp_path / "s.toml"
    path.write_text(text.replace("radius_m = 1.2", "raduis_m = 1.2", 1), encoding="utf-8")
    with pytest.raises(ConfigError) as caught:
        load_scenario(path)
    assert str(caught.value) == (
        f"{path}: obstacles[1].raduis_m: unknown key (did you mean 'radius_m'? without it: "
        "obstacles[1].radius_m: required key is missing)"
    )


def test_a_real_key_two_letters_from_the_missing_one_is_not_called_a_typo() -> None:
    root = Table({"datum_lon_deg": 8.5}, "f.toml", "")
    with pytest.raises(ConfigError) as caught:
        root.number("datum_lat_deg")
    assert (caught.value.key, caught.value.problem) == ("datum_lat_deg", "required key is missing")


def test_a_slip_in_a_short_optional_key_gets_its_did_you_mean() -> None:
    # difflib alone finds nothing near "di" (ratio 0.5 to "id").
    table = Table({"di": "rock"}, "f.toml", "obstacles[0]")
    table.text("id", "obstacle0")
    with pytest.raises(ConfigError) as caught:
        table.finish()
    assert caught.value.key == "obstacles[0].di"
    assert caught.value.problem.startswith("unknown key (did you mean 'id'? "), caught.value.problem
