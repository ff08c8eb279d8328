"""Campaign summary in the shape of the paper's tables, as Markdown and JSON.

Table 1 (per terrain and variant, averaged over seeds): path accuracy % (of the planned *route*,
``route_accuracy_pct``: a run that rolls over a fifth of the way scores at most about a fifth),
obstacle-avoidance success %, rollovers (mean per trial, as the paper's "Stability (No. of Rollovers)"),
plus path accuracy % of the driven distance (``path_accuracy_pct``: the driven distance spent within
tolerance of the path, which says how well a run tracked while it lasted, not how much of the route it
did), energy Wh/m, duration,
collisions, the ground-truth distance to the goal at the end, the share of trials whose rover reported
ARRIVED (``goal_reached``, judged on its estimate) and the share meeting the scenario's success criteria
(docs/metrics.md defines both accuracies); the means are over the trials that ran, and a row with trials
that errored (no metrics) says so in its Trials cell ("3 (2 errors: means of 1)"). Table 2: the same per
run (seed), as the paper lists its simulation runs, with each failed criterion in words. Every figure
comes from the trials' ``metrics.json``; the JSON's means are rounded to six significant digits, its
seconds to the millisecond. The header says what "encountered" meant for the obstacle-avoidance figures:
the encounter margins the trials recorded (``encounter_margin_m``, distinct values; ``encounter_margins_m``
in the JSON), and names the recordings in the folder the campaign did not write (``other_recordings``): an
earlier run's, which ``rover logs report`` of the folder reads and these tables leave out.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from hil.campaign import Campaign

# (metrics.json key, title, Table 1 format of the mean over seeds, Table 2 format of one run). Counts are
# whole numbers per run; their mean over seeds keeps two decimals, as the paper's rollover averages.
COLUMNS = (
    ("route_accuracy_pct", "Path Accuracy (% of route)", "{:.1f}", "{:.1f}"),
    ("obstacle_avoidance_success_pct", "Obstacle Avoidance Success (%)", "{:.1f}", "{:.1f}"),
    ("rollovers", "Stability (No. of Rollovers)", "{:.2f}", "{:d}"),
    ("path_accuracy_pct", "Path Accuracy (% of driven)", "{:.1f}", "{:.1f}"),
    ("energy_wh_per_m", "Energy (Wh/m)", "{:.4f}", "{:.4f}"),
    ("duration_s", "Duration (s)", "{:.1f}", "{:.1f}"),
    ("collisions", "Collisions", "{:.2f}", "{:d}"),
    # How near the rover's centre came to an obstacle's edge (docs/metrics.md): the encounter count only
    # says whether it came within the margin.
    ("closest_obstacle_m", "Closest Obstacle Approach (m)", "{:.2f}", "{:.2f}"),
    # Beside goal_reached (the rover's own ARRIVED, judged on its estimate): where it really stopped.
    ("final_distance_to_goal_m", "Final Distance to Goal (m, truth)", "{:.2f}", "{:.2f}"),
)
TABLE1_COLUMNS = tuple((key, title, mean_fmt) for key, title, mean_fmt, _run_fmt in COLUMNS)
SIGNIFICANT_DIGITS = 6  # means in summary.json: enough for Wh/m (~0.01) and seconds alike
TIME_DECIMALS = 3  # simulated and wall seconds: milliseconds (the physics step is 10 ms)


def _mean(values: list[float]) -> float | None:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    return _significant(sum(finite) / len(finite)) if finite else None


def _significant(value: float) -> float:
    """Rounded to ``SIGNIFICANT_DIGITS``: 38.800000000000004 -> 38.8, 0.0123456789 -> 0.0123457."""
    return float(f"{value:.{SIGNIFICANT_DIGITS}g}")


def summarise(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Table 1 rows: one per (terrain, variant) in first-seen order."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in rows:
        groups.setdefault((row["terrain"], row["variant"]), []).append(row)
    table = []
    for (terrain, variant), members in groups.items():
        entry: dict[str, Any] = {"terrain": terrain, "variant": variant, "trials": len(members)}
        ran = [m for m in members if m["ok"]]
        for key, _title, _fmt in TABLE1_COLUMNS:
            entry[key] = _mean([m["metrics"].get(key) for m in ran])
        reached = [m["metrics"].get("goal_reached") for m in ran]
        entry["goal_reached_pct"] = _mean([100.0 * bool(r) for r in reached if r is not None])
        entry["success_pct"] = _significant(100.0 * sum(1 for m in members if m["success"]) / len(members))
        entry["errors"] = len(members) - len(ran)
        table.append(entry)
    return table


def encounter_margins(rows: list[dict[str, Any]]) -> list[float]:
    """The distinct ``encounter_margin_m`` values (m) the trials that ran recorded, ascending."""
    margins = {m["metrics"].get("encounter_margin_m") for m in rows if m["ok"]}
    return sorted(
        float(v)
        for v in margins
        if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
    )


def _encounter_sentence(margins: list[float]) -> str:
    """What an encounter meant in these trials (docs/metrics.md has the definition)."""
    if not margins:
        return (
            "No trial recorded its encounter margin, so what counted as an encountered obstacle is unknown."
        )
    values = " or ".join(f"{m:g} m" for m in margins)
    per_scenario = " (per scenario)" if len(margins) > 1 else ""
    return (
        f"An obstacle counts as encountered when its edge came within {values}{per_scenario} of the rover's "
        "track, or the rover collided with it (`encounter_margin_m`; docs/metrics.md)."
    )


def rounded_times(row: dict[str, Any]) -> dict[str, Any]:
    """A Table 2 row with its simulated and wall seconds to the millisecond (float sums carry noise)."""
    return {
        **row,
        "simulated_s": round(row["simulated_s"], TIME_DECIMALS),
        "wall_s": round(row["wall_s"], TIME_DECIMALS),
    }


def others_sentence(out_dir: Path, others: list[str]) -> str:
    """What the summary says of recordings in its folder that the campaign did not write."""
    listed = ", ".join(others[:5]) + (f" and {len(others) - 5} more" if len(others) > 5 else "")
    return (
        f"{out_dir} also holds {len(others)} recording{'s' if len(others) > 1 else ''} this campaign did not "
        f"write ({listed}), perhaps of an earlier run into the same folder: the campaign's summary leaves "
        f"{'them' if len(others) > 1 else 'it'} out, while `rover logs report {out_dir}` reads every "
        "recording in the folder."
    )


def write_summary(
    campaign: Campaign, rows: list[dict[str, Any]], out_dir: Path, others: list[str] | None = None
) -> tuple[Path, Path]:
    """``others``: recordings in ``out_dir`` that the campaign did not write (``other_recordings``)."""
    others = others or []
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = [rounded_times(row) for row in rows]
    table1 = summarise(rows)
    json_path = out_dir / "summary.json"
    json_path.write_text(
        json.dumps(
            {
                "campaign": campaign.name,
                "source": campaign.source,
                "encounter_margins_m": encounter_margins(rows),
                "other_recordings": others,
                "table1": table1,
                "table2": rows,
            },
            indent=2,
            sort_keys=True,
        )
        + "\n",
        encoding="utf-8",
    )
    markdown_path = out_dir / "summary.md"
    markdown_path.write_text(
        _markdown(campaign, table1, rows, others_sentence(out_dir, others) if others else ""),
        encoding="utf-8",
    )
    return markdown_path, json_path


def _cell(value: Any, pattern: str) -> str:
    if value is None:
        return "n/a"
    if pattern == "{:d}" and isinstance(value, float) and value.is_integer():
        value = int(value)  # a count read back from JSON as 1.0
    return pattern.format(value)


def _trials_cell(entry: dict[str, Any]) -> str:
    """The trial count, and when some errored (no metrics), how many the row's means are of."""
    errors = entry["errors"]
    if not errors:
        return str(entry["trials"])
    return (
        f"{entry['trials']} ({errors} error{'s' if errors > 1 else ''}: means of {entry['trials'] - errors})"
    )


def _goal_cell(value: Any) -> str:
    return "n/a" if value is None else ("yes" if value else "no")


def _text_cell(text: str) -> str:
    return text.replace("|", "\\|")


def _markdown(campaign: Campaign, table1: list[dict[str, Any]], rows: list[dict[str, Any]], note: str) -> str:
    titles = [title for _key, title, _mean_fmt, _run_fmt in COLUMNS]
    lines = [
        f"# Campaign {campaign.name}",
        "",
        f"Source: `{Path(campaign.source).name}`; seeds {list(campaign.seeds)}. "
        "Every figure is computed from each trial's metrics.json (from its MCAP). Goal reached is the "
        "rover's own ARRIVED (judged on its estimate); the final distance to goal is the ground truth. "
        + _encounter_sentence(encounter_margins(rows))
        + (f" {note}" if note else ""),
        "",
        "## Table 1. Average results across terrains",
        "",
        "| Terrain Type | Variant | Trials | " + " | ".join(titles) + " | Goal Reached (%) | Success (%) |",
        "|---|---|---:|" + "---:|" * len(titles) + "---:|---:|",
    ]
    for entry in table1:
        cells = [_cell(entry[key], mean_fmt) for key, _title, mean_fmt, _run_fmt in COLUMNS]
        lines.append(
            f"| {entry['terrain']} | {entry['variant']} | {_trials_cell(entry)} | "
            + " | ".join(cells)
            + f" | {_cell(entry['goal_reached_pct'], '{:.0f}')} | {entry['success_pct']:.0f} |"
        )
    lines += [
        "",
        "## Table 2. Results per run",
        "",
        "| Terrain Type | Variant | Simulation Run (seed) | End | "
        + " | ".join(titles)
        + " | Goal Reached | Success | Failed Criteria |",
        "|---|---|---:|---|" + "---:|" * len(titles) + "---|---|---|",
    ]
    for row in rows:
        metrics = row["metrics"]
        cells = [_cell(metrics.get(key), run_fmt) for key, _title, _mean_fmt, run_fmt in COLUMNS]
        end = row["end_reason"] if row["ok"] else f"error: {_text_cell(row['error'])}"
        failed = "; ".join(row["failures"]) if row["ok"] else "(trial did not run to the end)"
        lines.append(
            f"| {row['terrain']} | {row['variant']} | {row['seed']} | {end} | "
            + " | ".join(cells)
            + f" | {_goal_cell(metrics.get('goal_reached'))} | {'yes' if row['success'] else 'no'}"
            + f" | {_text_cell(failed) or '-'} |"
        )
    return "\n".join(lines) + "\n"
