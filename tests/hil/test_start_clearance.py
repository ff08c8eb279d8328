"""An obstacle overlapping the rover's body at the start is refused before anything runs (exit 2, naming
the scenario file and the key). The load-time check only looked at the start *point*: a boulder 0.9 m
ahead with a 0.6 m radius, or a cart waiting at the start, passed, and the trial recorded a collision
0.01 s in, before the rover had moved (then timed out, exit 1)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.campaign import load_campaign
from hil.scenario import load_scenario
from hil.start_clearance import check_start_clear
from logs.settings import ConfigError
from navigator.vehicle import VehicleParams
from rover_cli.main import main

REPO = Path(__file__).resolve().parents[2]
BASE = """name = "start-check"
duration_s = 20.0
[terrain]
kind = "procedural"
size_m = [12.0, 8.0]
resolution_m = 0.25
class = "firm"
seed = 1
hill_height_m = 0.0
[start]
xy = [START_X, 4.0]
yaw_deg = 0.0
[[goals]]
xy = [10.5, 4.0]
"""
CLEAR_BOULDER = '[[obstacles]]\nid = "far"\nxy = [6.0, 6.5]\nradius_m = 0.5\n'
CART = (
    '[[moving_obstacles]]\nid = "cart"\nradius_m = 0.4\nspeed_mps = 0.5\nwaypoints = [[X, 4.0], [X, 7.0]]\n'
)


def _scenario(tmp_path: Path, extra: str, start_x: float = 2.0) -> Path:
    path = tmp_path / "scenario.toml"
    path.write_text(BASE.replace("START_X", str(start_x)) + CLEAR_BOULDER + extra)
    return path


CASES = [
    # A boulder 0.9 m ahead, radius 0.6: the start point is outside it, the body's front (0.45 m) is not.
    ('[[obstacles]]\nid = "rock"\nxy = [2.9, 4.0]\nradius_m = 0.6\n', 2.0, "obstacles[1].xy", "'rock'"),
    # A cart waiting at its first waypoint beside the rover, 0.6 m to the left: the body is 0.35 m wide.
    (CART.replace("X", "2.0").replace("4.0]", "4.6]", 1), 2.0, "moving_obstacles[0].waypoints", "'cart'"),
    ("", 0.3, "start.xy", "map's edge"),  # the rectangle's back reaches past x = 0
]


@pytest.mark.parametrize(("extra", "start_x", "key", "named"), CASES)
def test_a_body_overlapping_something_at_the_start_is_refused_naming_the_key(
    tmp_path: Path, extra: str, start_x: float, key: str, named: str
) -> None:
    scenario = load_scenario(_scenario(tmp_path, extra, start_x))  # the start point alone is clear
    with pytest.raises(ConfigError) as caught:
        check_start_clear(scenario, VehicleParams())
    assert caught.value.source == str(tmp_path / "scenario.toml") and caught.value.key == key
    assert named in caught.value.problem and "first tick" in caught.value.problem


@pytest.mark.parametrize(("extra", "start_x", "key", "named"), CASES[:2])
def test_rover_hil_trial_exits_2_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: str, start_x: float, key: str, named: str
) -> None:
    path = _scenario(tmp_path, extra, start_x)
    out = tmp_path / "out"
    assert main(["hil", "trial", str(path), "--out", str(out), "--no-telemetry"]) == 2
    printed = " ".join(capsys.readouterr().out.split())
    assert f"{path}: {key}: " in printed
    assert not out.exists()


def test_a_clear_start_passes(tmp_path: Path) -> None:
    check_start_clear(load_scenario(_scenario(tmp_path, CART.replace("X", "6.0"))), VehicleParams())


@pytest.mark.parametrize("path", sorted((REPO / "scenarios").glob("*.toml")), ids=lambda p: p.name)
def test_the_shipped_scenarios_start_clear(path: Path) -> None:
    check_start_clear(load_scenario(path), VehicleParams())


def test_a_campaign_variant_whose_footprint_overlaps_is_refused(tmp_path: Path) -> None:
    # Clear for the default 0.9 m body (gap 0.05 m ahead), not for a variant's 1.2 m long one.
    _scenario(tmp_path, '[[obstacles]]\nid = "rock"\nxy = [3.0, 4.0]\nradius_m = 0.5\n')
    campaign = tmp_path / "camp.toml"
    campaign.write_text(
        'name = "c"\nseeds = [1]\n[[terrains]]\nname = "t"\nscenario = "scenario.toml"\n'
        '[[variants]]\nname = "small"\n'
        '[[variants]]\nname = "long"\n[variants.overrides]\nvehicle.footprint_length_m = 1.2\n'
    )
    with pytest.raises(ConfigError) as caught:
        load_campaign(campaign)
    assert caught.value.source == str(campaign) and caught.value.key == "terrains[0].scenario"
    assert "variant 'long'" in caught.value.problem
    assert f"{tmp_path / 'scenario.toml'}: obstacles[1].xy" in caught.value.problem
