"""Bad campaign files and options: refused before the first trial, naming the campaign file and the key."""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

import pytest

from hil.campaign import load_campaign
from logs.settings import ConfigError
from rover_cli.main import build_parser, main

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "small_rocky.toml"


def _campaign(tmp_path: Path, terrain: str = "rocky", variant: str = "v", extra: str = "") -> Path:
    path = tmp_path / "camp.toml"
    path.write_text(
        f'name = "c"\nseeds = [1]\n{extra}\n'
        f'[[terrains]]\nname = "{terrain}"\nscenario = "{SCENARIO}"\n'
        f'[[variants]]\nname = "{variant}"\n'
    )
    return path


@pytest.mark.parametrize("name", ["../../escaped-terrain", "muddy/crossing", "..", ".", "", "a b", "ok,no"])
@pytest.mark.parametrize("table", ["terrains", "variants"])
def test_names_that_are_not_safe_path_components_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, table: str
) -> None:
    path = _campaign(tmp_path, **{table[:-1]: name})
    with pytest.raises(ConfigError) as caught:
        load_campaign(path)
    assert caught.value.source == str(path) and caught.value.key == f"{table}[0].name"
    out = tmp_path / "out"
    assert main(["hil", "campaign", str(path), "--out", str(out)]) == 2
    assert f"{path}: {table}[0].name" in capsys.readouterr().out
    assert not out.exists() and not (tmp_path.parent / "escaped-terrain").exists()


def test_the_campaign_name_is_a_safe_path_component_too(tmp_path: Path) -> None:
    # It names the default output folder, logs/trials/campaign-<name>.
    path = _campaign(tmp_path)
    path.write_text(path.read_text().replace('name = "c"', 'name = "../up"', 1))
    with pytest.raises(ConfigError) as caught:
        load_campaign(path)
    assert caught.value.key == "name"


def test_safe_names_are_accepted(tmp_path: Path) -> None:
    campaign = load_campaign(_campaign(tmp_path, terrain="Rocky_2.v-1", variant="terrain-aware.v2"))
    assert [t for t, _ in campaign.terrains] == ["Rocky_2.v-1"]


@pytest.mark.parametrize(
    ("line", "key", "missing"),
    [
        ('config = "no-such-rover.toml"', "config", "no-such-rover.toml"),
        ("", "terrains[0].scenario", "mine_mudy.toml"),
    ],
)
def test_a_missing_file_is_named_with_the_campaign_file_and_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], line: str, key: str, missing: str
) -> None:
    path = _campaign(tmp_path, extra=line)
    if not line:
        path.write_text(path.read_text().replace(str(SCENARIO), "mine_mudy.toml"))
    with pytest.raises(ConfigError) as caught:
        load_campaign(path)
    assert caught.value.source == str(path) and caught.value.key == key
    assert missing in caught.value.problem and "file not found" in caught.value.problem
    assert main(["hil", "campaign", str(path), "--out", str(tmp_path / "out")]) == 2
    printed = capsys.readouterr().out
    assert f"{path}: {key}: " in printed and missing in printed


def test_a_bad_scenario_names_the_campaign_key_and_the_scenario_key(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENARIO.read_text().replace("duration_s", "duraton_s"))
    path = _campaign(tmp_path)
    path.write_text(path.read_text().replace(str(SCENARIO), str(bad)))
    with pytest.raises(ConfigError) as caught:
        load_campaign(path)
    assert caught.value.key == "terrains[0].scenario"
    assert f"{bad}: duraton_s: unknown key" in caught.value.problem


def test_workers_zero_means_one_per_core_on_the_command_line_as_in_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = _campaign(tmp_path, extra="workers = 0")
    assert load_campaign(path).worker_count() == max(1, os.cpu_count() or 1)
    assert load_campaign(path).worker_count(3) == 3
    assert load_campaign(path).worker_count(0) == max(1, os.cpu_count() or 1)
    seen: dict[str, Any] = {}

    def fake_run(campaign: Any, out_dir: Path, *, workers: int | None, on_done: Any) -> Any:
        seen["workers"] = workers
        raise SystemExit(0)  # the option got through; the trials themselves are another test's

    monkeypatch.setattr("hil.campaign_runner.run_campaign", fake_run)
    with pytest.raises(SystemExit):
        main(["hil", "campaign", str(path), "--workers", "0", "--out", str(tmp_path / "out")])
    assert seen == {"workers": 0}


@pytest.mark.parametrize("workers", ["-1", "257", "two"])
def test_bad_worker_counts_are_refused_by_the_parser(
    workers: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as stopped:
        build_parser("hil").parse_args(["hil", "campaign", "x.toml", "--workers", workers])
    assert stopped.value.code == 2 and "--workers" in capsys.readouterr().err


def test_workers_zero_is_parsed(tmp_path: Path) -> None:
    args: argparse.Namespace = build_parser("hil").parse_args(["hil", "campaign", "x.toml", "--workers", "0"])
    assert args.workers == 0
