"""Bad scenario and config files: one readable error naming the file and key; nothing starts."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.scenario import load_scenario
from logs.settings import ConfigError
from navigator.config import load_rover_config
from rover_cli.main import main

DATA = Path(__file__).resolve().parents[1] / "data"


def test_missing_scenario_names_the_file(tmp_path):
    with pytest.raises(ConfigError, match=r"nope\.toml: file not found"):
        load_scenario(tmp_path / "nope.toml")


def test_malformed_toml_names_the_file(tmp_path):
    bad = tmp_path / "broken.toml"
    bad.write_text("name = \n[terrain\n")
    with pytest.raises(ConfigError, match=r"broken\.toml: not valid TOML"):
        load_scenario(bad)


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ("radius_m = 0.8", 'radius_m = "big"', "obstacles[0].radius_m"),
        ("xy = [11.5, 7.5]", "xy = [99.0, 7.5]", "goals[0].xy"),
        ('kind = "procedural"', 'kind = "lunar"', "terrain.kind"),
        ('class = "rocky"', 'class = "lava"', "terrain.class"),
        ("duration_s = 45.0", "duraton_s = 45.0", "duraton_s"),
    ],
)
def test_bad_scenario_value_names_the_key(tmp_path, old, new, key):
    text = (DATA / "small_rocky.toml").read_text()
    assert old in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(old, new))
    with pytest.raises(ConfigError) as caught:
        load_scenario(bad)
    assert caught.value.source.endswith("bad.toml")
    assert caught.value.key == key


def test_bad_rover_config_names_the_key(tmp_path):
    bad = tmp_path / "rover.toml"
    bad.write_text('[can]\ninterface = "carrier-pigeon"\n')
    with pytest.raises(ConfigError) as caught:
        load_rover_config(bad)
    assert caught.value.key == "can.interface"


def test_cli_refuses_bad_scenario_before_starting(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text((DATA / "small_rocky.toml").read_text().replace("radius_m = 0.8", "radius_m = -1"))
    out = tmp_path / "out"
    code = main(["hil", "trial", str(bad), "--out", str(out), "--no-telemetry"])
    assert code == 2
    assert "obstacles[0].radius_m" in capsys.readouterr().out
    assert not out.exists()


def test_shipped_files_load():
    root = Path(__file__).resolve().parents[2]
    load_rover_config(root / "configs" / "rover.toml")
    for scenario in sorted((root / "scenarios").glob("*.toml")):
        load_scenario(scenario)
