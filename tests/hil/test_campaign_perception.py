"""A campaign variant may set how the rover perceives obstacles (``perception``), in place of each scenario's
``[sensors] perception``: the simulator's objects against a lidar's scans and a ring of rangefinders, side by
side in Tables 1 and 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.campaign import load_campaign
from hil.campaign_runner import run_one
from logs.reader import read_metadata
from logs.settings import ConfigError

DATA = Path(__file__).resolve().parents[1] / "data"
REPO = Path(__file__).resolve().parents[2]


def _campaign(tmp_path: Path, variants: str) -> Path:
    path = tmp_path / "camp.toml"
    path.write_text(
        f'name = "c"\nseeds = [4]\n[[terrains]]\nname = "rock"\nscenario = "{DATA / "hidden_rock.toml"}"\n'
        + variants
    )
    return path


def test_each_variant_runs_with_its_perception_and_the_recording_says_so(tmp_path: Path) -> None:
    campaign = load_campaign(
        _campaign(
            tmp_path,
            '[[variants]]\nname = "objects"\nperception = "objects"\n'
            '[[variants]]\nname = "as-the-scenario"\n'
            '[[variants]]\nname = "ring"\nperception = "rangefinders"\n'
            "[variants.overrides]\nperception.rangefinders = [{ id = 0 }, { id = 1 }, { id = 2 }]\n",
        )
    )
    specs = campaign.trials(tmp_path / "out")
    assert [s.perception for s in specs] == ["objects", None, "rangefinders"]
    recorded = []
    for spec in specs:
        outcome = run_one(spec)
        assert outcome.success, outcome
        recorded.append(read_metadata(spec.out_dir / "trial.mcap")["scenario"]["perception"])
    assert recorded == ["objects", "scan", "rangefinders"]  # hidden_rock.toml itself says "scan"


def test_a_perception_no_model_has_is_named_under_the_variant(tmp_path: Path) -> None:
    path = _campaign(tmp_path, '[[variants]]\nname = "v"\nperception = "radar"\n')
    with pytest.raises(ConfigError) as caught:
        load_campaign(path)
    assert caught.value.key == "variants[0].perception" and "must be one of" in caught.value.problem


def test_the_shipped_perception_campaign_loads_every_model() -> None:
    campaign = load_campaign(REPO / "campaigns" / "perception.toml")
    assert [(v.name, v.perception) for v in campaign.variants] == [
        ("objects", "objects"),
        ("lidar-scans", "scan"),
        ("rangefinders", "rangefinders"),
    ]
    assert [t for t, _ in campaign.terrains] == ["hidden-boulders", "carts"]
