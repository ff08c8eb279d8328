"""A file of one kind (scenario, campaign, rover config) given where another kind goes is named as that
mix-up, not as the first key the other kind of file does not have ("name: required key is missing",
"terrains: required key is missing", "description: unknown key")."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from hil.campaign import load_campaign
from hil.scenario import load_scenario
from logs.file_kinds import CAMPAIGN, KINDS, ROVER_CONFIG, SCENARIO, FileKind, kind_of
from logs.settings import ConfigError, load_toml
from navigator.config import load_rover_config
from navigator.rover_process import check_runnable
from rover_cli.main import main

ROOT = Path(__file__).resolve().parents[2]
FILES = {
    SCENARIO: sorted(str(p.relative_to(ROOT)) for p in (ROOT / "scenarios").glob("*.toml")),
    CAMPAIGN: sorted(str(p.relative_to(ROOT)) for p in (ROOT / "campaigns").glob("*.toml")),
    ROVER_CONFIG: sorted(str(p.relative_to(ROOT)) for p in (ROOT / "configs").glob("*.toml")),
}
LOADERS: dict[FileKind, Callable[[Path], object]] = {
    SCENARIO: load_scenario,
    CAMPAIGN: load_campaign,
    ROVER_CONFIG: load_rover_config,
}


@pytest.mark.parametrize(
    ("kind", "name"), [(kind, name) for kind in KINDS for name in FILES[kind]], ids=lambda v: str(v)
)
def test_every_shipped_file_is_told_as_its_kind(kind: FileKind, name: str) -> None:
    assert kind_of(load_toml(ROOT / name)) is kind


@pytest.mark.parametrize(
    ("expected", "found", "name"),
    [
        (expected, found, name)
        for expected in KINDS
        for found in KINDS
        if found is not expected
        for name in FILES[found][:2]
    ],
    ids=lambda v: v.noun.replace(" ", "-") if isinstance(v, FileKind) else v,
)
def test_a_file_of_another_kind_is_named_as_that_mix_up(
    expected: FileKind, found: FileKind, name: str
) -> None:
    with pytest.raises(ConfigError) as caught:
        LOADERS[expected](ROOT / name)
    assert caught.value.key == "", str(caught.value)
    problem = caught.value.problem
    assert problem.startswith(f"this is a {found.noun} (it has "), problem
    assert (
        f"), not a {expected.noun}: a {expected.noun} ({expected.example}) goes here; {found.goes}" in problem
    )


@pytest.mark.parametrize(
    ("command", "said"),
    [
        (
            ["hil", "campaign", "scenarios/default.toml"],
            "this is a scenario (it has [terrain], [start] and [[goals]])",
        ),
        (
            ["hil", "trial", "campaigns/paper.toml"],
            "this is a campaign (it has [[terrains]], [[variants]] and seeds)",
        ),
        (
            ["hil", "campaign", "configs/rover.toml"],
            "this is a rover config (it has [vehicle], [vesc] and [can])",
        ),
    ],
)
def test_the_reviews_mix_ups_are_named_by_the_cli(
    command: list[str], said: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(ROOT)
    assert main([*command, "--out", "/nonexistent/never-written"]) == 2
    out = " ".join(capsys.readouterr().out.split())  # rich wraps long lines
    assert said in out, out


def test_a_scenario_given_to_rover_run_suggests_a_config_rover_run_takes(
    caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    # It had suggested configs/rover.toml, whose in-process MAVLink pipe `rover run` then refuses.
    monkeypatch.chdir(ROOT)
    assert main(["run", "--config", "scenarios/default.toml", "--no-telemetry"]) == 2
    (said,) = [record.getMessage() for record in caplog.records]
    assert "this is a scenario" in said and "`rover run` on the rover starts from " in said, said
    suggested = said.split("`rover run` on the rover starts from ")[1].split(")")[0]
    check_runnable(load_rover_config(ROOT / suggested))  # raises if `rover run` would refuse it


def test_a_rover_config_of_its_map_alone_is_named_as_one(tmp_path: Path) -> None:
    # [map] is a rover config's table too; a config holding only it read as "name: required key is missing".
    config = tmp_path / "map-only.toml"
    config.write_text('[map]\nkind = "procedural"\nsize_m = [10.0, 10.0]\nresolution_m = 0.5\n')
    with pytest.raises(ConfigError) as caught:
        load_scenario(config)
    assert caught.value.problem.startswith("this is a rover config (it has [map])"), caught.value.problem


def test_a_file_with_keys_of_two_kinds_is_left_to_the_loaders_own_errors(tmp_path: Path) -> None:
    # A scenario with a stray rover-config table: its key is what is wrong, not the whole file.
    text = (ROOT / "scenarios/default.toml").read_text(encoding="utf-8")
    path = tmp_path / "s.toml"
    path.write_text(text + "\n[perception]\nmount_forward_m = 0.3\n", encoding="utf-8")
    with pytest.raises(ConfigError) as caught:
        load_scenario(path)
    assert caught.value.key == "perception" and caught.value.problem.startswith("unknown key"), caught.value


def test_a_campaign_variants_overrides_are_not_told_as_a_file(tmp_path: Path) -> None:
    # Overrides merged over no base config are no file: a scenario's [sensors] there is an unknown key.
    campaign = tmp_path / "camp.toml"
    campaign.write_text(
        f'name = "c"\n[[terrains]]\nname = "t"\nscenario = "{ROOT / "scenarios/default.toml"}"\n'
        '[[variants]]\nname = "v"\n[variants.overrides]\nsensors.perception = "scan"\n',
        encoding="utf-8",
    )
    with pytest.raises(ConfigError) as caught:
        load_campaign(campaign)
    assert caught.value.key == "variants[0].overrides.sensors", caught.value
    assert caught.value.problem.startswith("unknown key"), caught.value


@pytest.mark.parametrize(
    "slips",
    ['[[terrain]]\nname = "rocky"\nscenario = "x.toml"\n', 'seed = [1]\n[[terrain]]\nname = "rocky"\n'],
)
def test_a_typo_of_the_expected_kinds_key_is_named_as_a_typo_not_a_mix_up(tmp_path: Path, slips: str) -> None:
    # [[terrain]] for [[terrains]] (and seed for seeds) left a campaign with scenario keys alone: it was
    # called "a scenario, not a campaign", which hides the slip (a reviewer's case).
    campaign = tmp_path / "c.toml"
    campaign.write_text(f'name = "mini"\n{slips}', encoding="utf-8")
    with pytest.raises(ConfigError) as caught:
        load_campaign(campaign)
    assert "did you mean" in caught.value.problem and "this is a" not in caught.value.problem, caught.value
