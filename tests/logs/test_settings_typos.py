"""An unknown key in a settings file names the nearest known key (a typo is the usual cause)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.campaign import load_campaign
from logs.settings import ConfigError, parse_toml
from navigator.config import rover_config_from_table
from tests.logs.small_scenario import SMALL_SCENARIO, load_text


@pytest.mark.parametrize(
    ("text", "key", "guess"),
    [
        ('[can]\nchanel = "can0"\n', "can.chanel", "did you mean 'channel'?"),
        ("[safety]\ngeofence = []\n", "safety.geofence", "did you mean 'fence'?"),
        ("control_rate = 50.0\n", "control_rate", "did you mean 'control_rate_hz'?"),
    ],
)
def test_a_typo_names_the_key_meant(text: str, key: str, guess: str) -> None:
    with pytest.raises(ConfigError) as caught:
        rover_config_from_table(parse_toml(text, "rover.toml"))
    assert caught.value.key == key
    assert caught.value.problem.startswith(f"unknown key ({guess} known here: "), caught.value.problem


def test_a_typo_of_a_key_read_only_when_present_names_it(tmp_path: Path) -> None:
    """Optional keys read only after ``has()`` (a campaign's ``config``, a scenario's ``[success]
    max_collisions``) were missing from the known keys: `confg = ...` in a campaign said "known here:
    description, name, seeds, ...", without config, and `max_colisions` said "did you mean
    'max_rollovers'?"."""
    table = parse_toml("max_colisions = 0\n", "scenario.toml")
    assert not table.has("max_collisions")
    table.integer("max_rollovers", 0)
    with pytest.raises(ConfigError) as caught:
        table.finish()
    assert caught.value.problem.startswith("unknown key (did you mean 'max_collisions'? "), caught.value
    assert caught.value.key == "max_colisions"

    scenario = Path(__file__).resolve().parents[2] / "scenarios" / "rocky.toml"
    campaign = tmp_path / "campaign.toml"
    campaign.write_text(
        f'name = "c"\nconfg = "rover.toml"\n[[terrains]]\nname = "rocky"\nscenario = "{scenario}"\n',
        encoding="utf-8",
    )
    with pytest.raises(ConfigError) as caught:
        load_campaign(campaign)
    assert caught.value.key == "confg"
    assert "did you mean 'config'?" in caught.value.problem and "seed_count" in caught.value.problem


@pytest.mark.parametrize(
    ("tail", "key", "guess"),
    [
        # Keys read only when present (optional, no default) are known keys too: a typo in one names it.
        ('[[faults]]\ntarget = "gps"\nkind = "off"\nduraton_s = 4.0\n', "faults[0].duraton_s", "duration_s"),
        ("[success]\nmax_colisions = 0\n", "success.max_colisions", "max_collisions"),
        ("[success]\nmax_final_distance = 0.5\n", "success.max_final_distance", "max_final_distance_m"),
    ],
)
def test_a_typo_in_a_key_read_only_when_present_names_it(tail: str, key: str, guess: str) -> None:
    with pytest.raises(ConfigError) as caught:
        load_text(SMALL_SCENARIO + tail)
    assert caught.value.key == key
    assert caught.value.problem.startswith(f"unknown key (did you mean {guess!r}? known here: "), (
        caught.value.problem
    )
    assert guess in caught.value.problem.partition("known here: ")[2]


@pytest.mark.parametrize(
    ("written", "meant"),
    [("radius", "radius_m"), ("Radius_M", "radius_m"), ("XY", "xy"), ("resolution", "resolution_m")],
)
def test_a_key_without_its_unit_or_in_other_case_is_named_as_the_key_meant(written: str, meant: str) -> None:
    # More than one slip apart, yet the likeliest mistakes: without them, "radius_m: required key is
    # missing" never named what was written.
    table = parse_toml(f"{written} = 1.0\n", "scenario.toml")
    with pytest.raises(ConfigError) as caught:
        table.number(meant)
    assert caught.value.key == written
    assert caught.value.problem.startswith(f"unknown key (did you mean {meant!r}? "), caught.value
