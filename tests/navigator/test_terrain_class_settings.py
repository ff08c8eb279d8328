"""``[terrain_classes.<name>]`` in a rover config and a scenario: what each side may set, each bad input
refused under its key path, and a table that is the default when nothing is written."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from logs.file_kinds import ROVER_CONFIG, SCENARIO, kind_of, refuse_another_kind
from logs.settings import ConfigError, Table, parse_toml
from navigator.config import RoverConfig, rover_config_from_table
from navigator.terrain_class_settings import PHYSICS_FIELDS, PLANNER_FIELDS, overrides_flat
from navigator.terrain_classes import SANDY, TERRAIN_CLASSES, TerrainClass
from tests.logs.small_scenario import SMALL_SCENARIO, load_text


def config_of(text: str) -> RoverConfig:
    return rover_config_from_table(parse_toml(text, "rover.toml"))


def test_every_figure_of_a_class_can_be_set_on_one_side_or_the_other() -> None:
    # A field added to TerrainClass must be added to the tables too, or a team could not set it.
    numbers = {f.name for f in dataclasses.fields(TerrainClass) if f.type in ("float", float)}
    assert set(PHYSICS_FIELDS) | set(PLANNER_FIELDS) == numbers
    assert not set(PHYSICS_FIELDS) & set(PLANNER_FIELDS)


def test_without_tables_both_sides_have_the_built_in_table() -> None:
    assert config_of("").classes == TERRAIN_CLASSES
    assert config_of("").terrain_classes == {}
    assert load_text(SMALL_SCENARIO).classes == TERRAIN_CLASSES


def test_a_config_sets_any_field_and_the_rest_keep_the_tables_values() -> None:
    config = config_of("[terrain_classes.sandy]\nfriction_mu = 0.45\ncost_factor = 3.5\n")
    sandy = config.classes[SANDY]
    assert (sandy.friction_mu, sandy.cost_factor) == (0.45, 3.5)
    default = TERRAIN_CLASSES[SANDY]
    assert dataclasses.replace(sandy, friction_mu=0.4, cost_factor=2.0, source=default.source) == default
    assert {i: c for i, c in config.classes.items() if i != SANDY} == {
        i: c for i, c in TERRAIN_CLASSES.items() if i != SANDY
    }
    assert "friction_mu, cost_factor set in [terrain_classes.sandy]" in sandy.source
    assert overrides_flat(config.terrain_classes) == {
        "terrain_classes.sandy.friction_mu": "0.45",
        "terrain_classes.sandy.cost_factor": "3.5",
    }


def test_a_scenario_sets_the_physics_fields() -> None:
    text = (
        SMALL_SCENARIO
        + "[terrain_classes.muddy]\n"
        + "".join(f"{key} = {getattr(TERRAIN_CLASSES[3], key) * 0.9!r}\n" for key in PHYSICS_FIELDS)
    )
    muddy = load_text(text).classes[3]
    for key in PHYSICS_FIELDS:
        assert getattr(muddy, key) == pytest.approx(getattr(TERRAIN_CLASSES[3], key) * 0.9)
    assert muddy.cost_factor == TERRAIN_CLASSES[3].cost_factor


BAD_TABLES = [
    # (table text, the key path named, words the message must have)
    ("[terrain_classes.sandi]\nfriction_mu = 0.3", "terrain_classes.sandi", "did you mean 'sandy'"),
    ("[terrain_classes.beach]\nfriction_mu = 0.3", "terrain_classes.beach", "known classes: firm, rocky"),
    ("[terrain_classes.sandy]\nfriction_mu = 0.0", "terrain_classes.sandy.friction_mu", "friction_mu > 0"),
    ("[terrain_classes.sandy]\nfriction_mu = nan", "terrain_classes.sandy.friction_mu", "finite"),
    (
        "[terrain_classes.sandy]\nfriction_mu = '0.3'",
        "terrain_classes.sandy.friction_mu",
        "expected a number",
    ),
    ("[terrain_classes.sandy]\nslip_constant = 1.5", "terrain_classes.sandy.slip_constant", "(0, 1]"),
    # Within its own range, but below the built-in sinkage part: the key written is the one to blame.
    (
        "[terrain_classes.sandy]\nrolling_resistance = 0.05",
        "terrain_classes.sandy.rolling_resistance",
        "the built-in table's sinkage_resistance = 0.1",
    ),
    (
        "[terrain_classes.sandy]\nrolling_resistance = 0.2\nsinkage_resistance = 0.3",
        "terrain_classes.sandy.sinkage_resistance",
        "[0, rolling_resistance]",
    ),
    # Both named by the check's message; the one whose built-in value passes is the one to blame.
    (
        "[terrain_classes.sandy]\nfriction_mu = 0.5\nrolling_resistance = -0.1",
        "terrain_classes.sandy.rolling_resistance",
        "rolling_resistance >= 0",
    ),
    ("[terrain_classes.sandy]\nfrictoin_mu = 0.3", "terrain_classes.sandy.frictoin_mu", "'friction_mu'"),
    ("[terrain_classes]\nsandy = 0.3", "terrain_classes.sandy", "expected a table"),
    ("terrain_classes = 1", "terrain_classes", "expected a table"),
]


@pytest.mark.parametrize(("table", "key", "words"), BAD_TABLES)
@pytest.mark.parametrize("side", ["config", "scenario"])
def test_bad_input_is_refused_under_its_key_path(side: str, table: str, key: str, words: str) -> None:
    with pytest.raises(ConfigError) as caught:
        if side == "config":
            config_of(table + "\n")
        elif table.startswith("["):
            load_text(SMALL_SCENARIO + table + "\n")
        else:  # a top-level key: before the scenario's tables, or TOML puts it in the last one
            load_text(table + "\n" + SMALL_SCENARIO)
    assert caught.value.key == key
    assert words in caught.value.problem


def test_a_config_cost_factor_below_firm_grounds_is_refused() -> None:
    with pytest.raises(ConfigError) as caught:
        config_of("[terrain_classes.grass]\ncost_factor = 0.5\n")
    assert caught.value.key == "terrain_classes.grass.cost_factor" and ">= 1.0" in caught.value.problem


def test_a_scenario_refuses_cost_factor_saying_whose_it_is() -> None:
    with pytest.raises(ConfigError) as caught:
        load_text(SMALL_SCENARIO + "[terrain_classes.sandy]\nfriction_mu = 0.3\ncost_factor = 3.0\n")
    assert caught.value.key == "terrain_classes.sandy.cost_factor"
    assert "planner's" in caught.value.problem and "rover config" in caught.value.problem


def test_the_file_kinds_are_still_told_apart_with_class_tables() -> None:
    classes = "[terrain_classes.sandy]\nfriction_mu = 0.3\n"
    scenario = parse_toml(SMALL_SCENARIO + classes, "s.toml")
    config = parse_toml("[planner]\ncost_mode = 'terrain'\n" + classes, "c.toml")
    assert kind_of(scenario) is SCENARIO and kind_of(config) is ROVER_CONFIG
    # Both kinds take the table, so it tells neither: a file of it alone is left to the loader.
    assert kind_of(parse_toml(classes, "x.toml")) is None
    with pytest.raises(ConfigError, match="this is a scenario"):
        refuse_another_kind(scenario, ROVER_CONFIG)
    with pytest.raises(ConfigError, match="this is a rover config"):
        refuse_another_kind(config, SCENARIO)
    refuse_another_kind(Table({"terrain_classes": {}}, "x.toml", ""), ROVER_CONFIG)  # no mix-up named


def test_the_shipped_configs_commented_example_loads_and_is_the_tables_sand() -> None:
    shipped = Path(__file__).resolve().parents[2] / "configs" / "rover.toml"
    text = shipped.read_text(encoding="utf-8")
    example = text[text.index("# [terrain_classes.sandy]") :]
    uncommented = re.sub(r"^# ", "", example, flags=re.MULTILINE)
    config = config_of(text + "\n" + uncommented)
    assert set(config.terrain_classes["sandy"]) == {*PHYSICS_FIELDS, *PLANNER_FIELDS}
    sandy, table = config.classes[SANDY], TERRAIN_CLASSES[SANDY]
    assert dataclasses.replace(sandy, source=table.source) == table
