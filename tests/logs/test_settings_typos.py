"""An unknown key in a settings file names the nearest known key (a typo is the usual cause)."""

from __future__ import annotations

import pytest

from logs.settings import ConfigError, parse_toml
from navigator.config import rover_config_from_table


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
