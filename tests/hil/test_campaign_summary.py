"""Campaign tables: whole counts per run, rounded JSON, failed criteria and truth goal distance shown."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hil.campaign import Campaign
from hil.campaign_summary import write_summary

CAMPAIGN = Campaign("mini", "mini.toml", (("rocky", Path("rocky.toml")),), (), (1, 2), None, 1)


def _row(seed: int, *, success: bool, failures: list[str], **metrics: Any) -> dict[str, Any]:
    base = {"collisions": 0, "rollovers": 0, "duration_s": 38.8, "goal_reached": True}
    return {
        "terrain": "rocky",
        "variant": "classical",
        "seed": seed,
        "ok": True,
        "end_reason": "arrived",
        "success": success,
        "failures": failures,
        "error": "",
        "mcap": None,
        "simulated_s": 38.800000000000004,
        "wall_s": 2.123456789,
        "metrics": {**base, **metrics},
    }


ROWS = [
    _row(1, success=True, failures=[], final_distance_to_goal_m=0.31, energy_wh_per_m=0.1),
    _row(
        2,
        success=False,
        failures=["final distance to goal (ground truth) 0.71 m > 0.5 m"],
        final_distance_to_goal_m=0.71,
        energy_wh_per_m=0.2,
    ),
]


def test_per_run_counts_are_whole_numbers_and_failures_are_named(tmp_path):
    markdown, _json_path = write_summary(CAMPAIGN, ROWS, tmp_path)
    table2 = markdown.read_text(encoding="utf-8").split("## Table 2")[1]
    header, _rule, first, second = table2.strip().splitlines()[-4:]
    columns = [c.strip() for c in header.strip("|").split("|")]
    cells = [[c.strip() for c in line.strip("|").split("|")] for line in (first, second)]
    at = {name: index for index, name in enumerate(columns)}
    assert cells[0][at["Collisions"]] == "0" and cells[0][at["Stability (No. of Rollovers)"]] == "0"
    assert cells[0][at["Goal Reached"]] == "yes"
    assert cells[1][at["Final Distance to Goal (m, truth)"]] == "0.71"
    assert cells[1][at["Success"]] == "no"
    assert cells[1][at["Failed Criteria"]] == "final distance to goal (ground truth) 0.71 m > 0.5 m"
    assert cells[0][at["Failed Criteria"]] == "-"


def test_summary_json_is_rounded(tmp_path):
    _markdown, json_path = write_summary(CAMPAIGN, ROWS, tmp_path)
    summary = json.loads(json_path.read_text(encoding="utf-8"))
    assert [row["simulated_s"] for row in summary["table2"]] == [38.8, 38.8]
    assert summary["table2"][0]["wall_s"] == 2.123
    (entry,) = summary["table1"]
    assert entry["energy_wh_per_m"] == 0.15  # 0.15000000000000002 before rounding
    assert entry["final_distance_to_goal_m"] == 0.51
    assert entry["goal_reached_pct"] == 100.0 and entry["success_pct"] == 50.0
    assert entry["collisions"] == 0.0


def test_the_header_says_what_encountered_meant(tmp_path):
    rows = [{**row, "metrics": {**row["metrics"], "encounter_margin_m": 1.5}} for row in ROWS]
    markdown, json_path = write_summary(CAMPAIGN, rows, tmp_path)
    header = markdown.read_text(encoding="utf-8").split("## Table 1")[0]
    assert "an obstacle counts as encountered when its edge came within 1.5 m of the rover's track" in (
        header.lower()
    )
    assert "docs/metrics.md" in header
    assert json.loads(json_path.read_text(encoding="utf-8"))["encounter_margins_m"] == [1.5]


def test_several_encounter_margins_are_all_named_and_a_missing_one_is_said(tmp_path):
    margins = [2.0, 1.0]  # two scenarios with their own margins; a trial that errored recorded none
    rows = [
        {**row, "metrics": {**row["metrics"], "encounter_margin_m": m}}
        for row, m in zip(ROWS, margins, strict=True)
    ]
    rows.append({**ROWS[0], "seed": 3, "ok": False, "error": "boom", "metrics": {}})
    markdown, json_path = write_summary(CAMPAIGN, rows, tmp_path)
    header = markdown.read_text(encoding="utf-8").split("## Table 1")[0]
    assert "within 1 m or 2 m (per scenario) of the rover's track" in header
    assert json.loads(json_path.read_text(encoding="utf-8"))["encounter_margins_m"] == [1.0, 2.0]

    markdown, json_path = write_summary(CAMPAIGN, ROWS, tmp_path / "older")  # metrics without the margin
    assert "No trial recorded its encounter margin" in markdown.read_text(encoding="utf-8")
    assert json.loads(json_path.read_text(encoding="utf-8"))["encounter_margins_m"] == []


def test_table_1_says_how_many_trials_its_means_are_of(tmp_path):
    """A row of 3 trials, 2 of which errored, read "| rocky | classical | 3 | 100.0 | ..." with every figure
    the one trial that ran: the means looked like those of 3 runs."""
    errored = [{**ROWS[0], "seed": s, "ok": False, "error": "boom", "metrics": {}} for s in (3, 4)]
    markdown, _json_path = write_summary(CAMPAIGN, [ROWS[0], *errored], tmp_path)
    table1 = markdown.read_text(encoding="utf-8").split("## Table 1")[1].split("## Table 2")[0]
    row = next(line for line in table1.splitlines() if line.startswith("| rocky |"))
    assert [c.strip() for c in row.strip("|").split("|")][2] == "3 (2 errors: means of 1)"
    markdown, _json_path = write_summary(CAMPAIGN, ROWS, tmp_path / "all-ran")
    table1 = markdown.read_text(encoding="utf-8").split("## Table 1")[1].split("## Table 2")[0]
    assert "| rocky | classical | 2 |" in table1


def test_the_closest_approach_is_a_column_of_both_tables(tmp_path):
    rows = [
        {**ROWS[0], "metrics": {**ROWS[0]["metrics"], "closest_obstacle_m": 0.8}},
        {**ROWS[1], "metrics": {**ROWS[1]["metrics"], "closest_obstacle_m": -0.1}},  # inside a radius
    ]
    markdown, json_path = write_summary(CAMPAIGN, rows, tmp_path)
    table2 = markdown.read_text(encoding="utf-8").split("## Table 2")[1]
    header, _rule, first, second = table2.strip().splitlines()[-4:]
    at = {name.strip(): index for index, name in enumerate(header.strip("|").split("|"))}
    cells = [[c.strip() for c in line.strip("|").split("|")] for line in (first, second)]
    assert [row[at["Closest Obstacle Approach (m)"]] for row in cells] == ["0.80", "-0.10"]
    (entry,) = json.loads(json_path.read_text(encoding="utf-8"))["table1"]
    assert entry["closest_obstacle_m"] == 0.35  # the mean over seeds, as every Table 1 figure
