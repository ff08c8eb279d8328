"""A variant's bad override is named in the campaign file, where it was written: the campaign file, then
``variants[i].overrides.<key>``. The error once led with the base rover config's path
(``configs/rover.toml + overrides of camp.toml variant 'classical': planner.cost_mod: ...``), which sent
people looking for the typo in rover.toml. A mistake in the base config itself is named under ``config``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.campaign import load_campaign
from logs.settings import ConfigError
from rover_cli.main import main

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "small_rocky.toml"


def _campaign(tmp_path: Path, overrides: str, base_config: str | None = None) -> Path:
    config_line = ""
    if base_config is not None:
        (tmp_path / "base.toml").write_text(base_config)
        config_line = 'config = "base.toml"\n'
    path = tmp_path / "camp.toml"
    path.write_text(
        f'name = "c"\nseeds = [1]\n{config_line}'
        f'[[terrains]]\nname = "rocky"\nscenario = "{SCENARIO}"\n'
        '[[variants]]\nname = "terrain-aware"\n[variants.overrides]\nplanner.cost_mode = "terrain"\n'
        f'[[variants]]\nname = "classical"\n[variants.overrides]\n{overrides}\n'
    )
    return path


@pytest.mark.parametrize(
    ("override", "key", "problem"),
    [
        ('planner.cost_mod = "classical"', "planner.cost_mod", "unknown key"),
        ('planer.cost_mode = "classical"', "planer", "unknown key"),
        ('planner.cost_mode = "classic"', "planner.cost_mode", "must be one of"),
        ("planner.heuristic_weight = 0.5", "planner.heuristic_weight", "must be >= 1.0"),
        ("follower.max_speed_mps = 4.0", "follower.max_speed_mps", "vehicle.max_wheel_speed_mps"),
    ],
)
@pytest.mark.parametrize("base", [None, '[planner]\nheuristic = "octile"\n'])
def test_a_bad_override_is_named_in_the_campaign_file_under_its_variant(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    override: str,
    key: str,
    problem: str,
    base: str | None,
) -> None:
    path = _campaign(tmp_path, override, base)
    with pytest.raises(ConfigError) as caught:
        load_campaign(path)
    assert caught.value.source == str(path)
    assert caught.value.key == f"variants[1].overrides.{key}"
    assert problem in caught.value.problem
    out = tmp_path / "out"
    assert main(["hil", "campaign", str(path), "--out", str(out)]) == 2
    printed = " ".join(capsys.readouterr().out.split())
    assert printed.startswith(f"error: {path}: variants[1].overrides.{key}: ")
    assert not out.exists()


def test_an_override_that_breaks_a_base_config_value_names_both(tmp_path: Path) -> None:
    # The override is in range; the base config's follower speed is what it now contradicts.
    path = _campaign(tmp_path, "vehicle.max_wheel_speed_mps = 0.5", "[follower]\nmax_speed_mps = 1.0\n")
    with pytest.raises(ConfigError) as caught:
        load_campaign(path)
    assert caught.value.source == str(path) and caught.value.key == "variants[1].overrides"
    assert str(tmp_path / "base.toml") in caught.value.problem
    assert "follower.max_speed_mps" in caught.value.problem


def test_a_mistake_in_the_base_config_is_named_under_config(tmp_path: Path) -> None:
    path = _campaign(tmp_path, 'planner.cost_mode = "classical"', '[planner]\ncost_mod = "terrain"\n')
    with pytest.raises(ConfigError) as caught:
        load_campaign(path)
    assert caught.value.source == str(path) and caught.value.key == "config"
    assert f"{tmp_path / 'base.toml'}: planner.cost_mod: unknown key" in caught.value.problem


def test_a_quoted_dotted_override_key_is_explained(tmp_path: Path) -> None:
    # TOML reads "planner.cost_mode" (quoted) as one key with a dot in its name, not cost_mode in
    # [planner]: "planner.cost_mode: unknown key" alone reads as if the real key were unknown.
    path = _campaign(tmp_path, '"planner.cost_mode" = "classical"')
    with pytest.raises(ConfigError) as caught:
        load_campaign(path)
    assert caught.value.key == "variants[1].overrides.planner.cost_mode"
    assert "unknown key" in caught.value.problem
    assert "one key with a dot in its name" in caught.value.problem
    assert "write it unquoted" in caught.value.problem


def test_a_quoted_dotted_key_in_a_rover_config_is_explained(tmp_path: Path) -> None:
    path = _campaign(tmp_path, 'planner.cost_mode = "classical"', '"planner.heuristic" = "octile"\n')
    with pytest.raises(ConfigError) as caught:
        load_campaign(path)
    assert caught.value.key == "config" and "one key with a dot in its name" in caught.value.problem
