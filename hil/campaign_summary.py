"""Campaign summary in the shape of the paper's tables, as Markdown and JSON.

Table 1 (per terrain and variant, averaged over seeds): path accuracy % (of the planned *route*,
``route_accuracy_pct``: a run that rolls over a fifth of the way scores at most about a fifth),
obstacle-avoidance success %, rollovers (mean per trial, as the paper's "Stability (No. of Rollovers)"),
plus path accuracy % of the driven distance (``path_accuracy_pct``: the driven distance spent within
tolerance of the path, which says how well a run tracked while it lasted, not how much of the route it
did), energy Wh/m, duration,
collisions and the share of trials meeting the scenario's success criteria (docs/metrics.md defines
both accuracies). Table 2: the same per run (seed), as the paper lists its simulation runs. Every
figure comes from the trials' ``metrics.json``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from hil.campaign import Campaign

TABLE1_COLUMNS = (
    ("route_accuracy_pct", "Path Accuracy (% of route)", "{:.1f}"),
    ("obstacle_avoidance_success_pct", "Obstacle Avoidance Success (%)", "{:.1f}"),
    ("rollovers", "Stability (No. of Rollovers)", "{:.2f}"),
    ("path_accuracy_pct", "Path Accuracy (% of driven)", "{:.1f}"),
    ("energy_wh_per_m", "Energy (Wh/m)", "{:.4f}"),
    ("duration_s", "Duration (s)", "{:.1f}"),
    ("collisions", "Collisions", "{:.2f}"),
)


def _mean(values: list[float]) -> float | None:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    return sum(finite) / len(finite) if finite else None


def summarise(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Table 1 rows: one per (terrain, variant) in first-seen order."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in rows:
        groups.setdefault((row["terrain"], row["variant"]), []).append(row)
    table = []
    for (terrain, variant), members in groups.items():
        entry: dict[str, Any] = {"terrain": terrain, "variant": variant, "trials": len(members)}
        for key, _title, _fmt in TABLE1_COLUMNS:
            entry[key] = _mean([m["metrics"].get(key) for m in members if m["ok"]])
        entry["success_pct"] = 100.0 * sum(1 for m in members if m["success"]) / len(members)
        entry["errors"] = sum(1 for m in members if not m["ok"])
        table.append(entry)
    return table


def write_summary(campaign: Campaign, rows: list[dict[str, Any]], out_dir: Path) -> tuple[Path, Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    table1 = summarise(rows)
    json_path = out_dir / "summary.json"
    json_path.write_text(
        json.dumps(
            {"campaign": campaign.name, "source": campaign.source, "table1": table1, "table2": rows},
            indent=2,
            sort_keys=True,
        )
        + "\n",
        encoding="utf-8",
    )
    markdown_path = out_dir / "summary.md"
    markdown_path.write_text(_markdown(campaign, table1, rows), encoding="utf-8")
    return markdown_path, json_path


def _cell(value: Any, pattern: str) -> str:
    return "n/a" if value is None else pattern.format(value)


def _markdown(campaign: Campaign, table1: list[dict[str, Any]], rows: list[dict[str, Any]]) -> str:
    titles = [title for _key, title, _fmt in TABLE1_COLUMNS]
    lines = [
        f"# Campaign {campaign.name}",
        "",
        f"Source: `{Path(campaign.source).name}`; seeds {list(campaign.seeds)}. "
        "Every figure is computed from each trial's metrics.json (from its MCAP).",
        "",
        "## Table 1. Average results across terrains",
        "",
        "| Terrain Type | Variant | Trials | " + " | ".join(titles) + " | Success (%) |",
        "|---|---|---:|" + "---:|" * len(titles) + "---:|",
    ]
    for entry in table1:
        cells = [_cell(entry[key], fmt) for key, _title, fmt in TABLE1_COLUMNS]
        lines.append(
            f"| {entry['terrain']} | {entry['variant']} | {entry['trials']} | "
            + " | ".join(cells)
            + f" | {entry['success_pct']:.0f} |"
        )
    lines += [
        "",
        "## Table 2. Results per run",
        "",
        "| Terrain Type | Variant | Simulation Run (seed) | End | " + " | ".join(titles) + " |",
        "|---|---|---:|---|" + "---:|" * len(titles),
    ]
    for row in rows:
        metrics = row["metrics"]
        cells = [_cell(metrics.get(key), fmt) for key, _title, fmt in TABLE1_COLUMNS]
        end = row["end_reason"] if row["ok"] else f"error: {row['error']}"
        lines.append(
            f"| {row['terrain']} | {row['variant']} | {row['seed']} | {end} | " + " | ".join(cells) + " |"
        )
    return "\n".join(lines) + "\n"
