"""Campaigns: variant overrides reach the config; trials run in workers; paper-shaped summary."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil.campaign import campaign_config, load_campaign
from hil.campaign_runner import run_campaign
from logs.settings import ConfigError

DATA = Path(__file__).resolve().parents[1] / "data"
ROOT = Path(__file__).resolve().parents[2]

CAMPAIGN = f"""
name = "mini"
seeds = [3]
workers = 2

[[terrains]]
name = "rocky"
scenario = "{DATA / "small_rocky.toml"}"

[[variants]]
name = "terrain-aware"
[variants.overrides]
planner.cost_mode = "terrain"

[[variants]]
name = "classical"
[variants.overrides]
planner.cost_mode = "classical"
"""


def test_variant_overrides_reach_the_rover_config():
    assert (
        campaign_config(None, {"planner": {"cost_mode": "classical"}}, "t").planner.cost_mode == "classical"
    )
    with pytest.raises(ConfigError, match=r"planner\.cost_mode"):
        campaign_config(None, {"planner": {"cost_mode": "psychic"}}, "t")
    with pytest.raises(ConfigError, match="planner"):
        campaign_config(None, {"planner": {"no_such_key": 1}}, "t")


def test_shipped_campaigns_load():
    for path in sorted((ROOT / "campaigns").glob("*.toml")):
        campaign = load_campaign(path)
        assert campaign.terrains and campaign.variants and campaign.seeds


def test_campaign_runs_every_trial_in_workers_and_writes_tables(tmp_path):
    path = tmp_path / "mini.toml"
    path.write_text(CAMPAIGN, encoding="utf-8")
    campaign = load_campaign(path)
    done = []
    outcomes, markdown, json_path = run_campaign(campaign, tmp_path / "out", on_done=done.append)
    assert len(done) == len(outcomes) == 2
    assert all(o.ok for o in outcomes), [o.error for o in outcomes]
    for outcome in outcomes:
        assert (outcome.spec.out_dir / "trial.mcap").stat().st_size > 0
    summary = json.loads(json_path.read_text(encoding="utf-8"))
    assert [(r["terrain"], r["variant"]) for r in summary["table1"]] == [
        ("rocky", "terrain-aware"),
        ("rocky", "classical"),
    ]
    for row, outcome in zip(summary["table2"], outcomes, strict=True):
        metrics = json.loads(outcome.metrics_path.read_text(encoding="utf-8"))
        assert row["metrics"] == metrics
    text = markdown.read_text(encoding="utf-8")
    assert (
        "Table 1" in text and "Path Accuracy (% of route)" in text and "Stability (No. of Rollovers)" in text
    )
    for entry in summary["table1"]:  # the route-based accuracy is there for every variant
        assert entry["route_accuracy_pct"] is not None


def test_a_campaign_report_keeps_the_campaign_terrains_and_variant_order(tmp_path):
    from logs.report import write_report

    path = tmp_path / "two.toml"
    # two campaign terrains on one scenario (one terrain class); "terrain-aware" is the first variant,
    # though "classical" sorts first by name
    path.write_text(
        CAMPAIGN + f'\n[[terrains]]\nname = "rocky-b"\nscenario = "{DATA / "small_rocky.toml"}"\n',
        encoding="utf-8",
    )
    campaign = load_campaign(path)
    outcomes, _, _ = run_campaign(campaign, tmp_path / "out")
    assert all(o.ok for o in outcomes), [o.error for o in outcomes]
    result = write_report([tmp_path / "out"], tmp_path / "report", plots=False)
    assert [(row["terrain"], row["variant"]) for row in result.terrain_table] == [
        ("rocky", "terrain-aware"),
        ("rocky", "classical"),
        ("rocky-b", "terrain-aware"),
        ("rocky-b", "classical"),
    ]
    assert all("collisions" in row for row in result.terrain_table)
    assert [Path(c.a).parent.parent.name for c in result.comparisons] == ["terrain-aware", "terrain-aware"]
