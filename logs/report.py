"""``rover logs report``: a self-contained HTML report, plus the same content as Markdown and JSON.

Inputs are recordings and/or directories (a campaign: every ``*.mcap`` below it). Each recording gets its
metrics, figures and plots; the first run is compared with each other run (aligned by distance); with more
than two runs, or a directory, the per-terrain table of the paper's metrics is added. A recording that
cannot be read at all is listed with the reason and the report goes on; one with missing topics gets a
partial section that lists what is missing.
"""

from __future__ import annotations

import html
import json
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from logs.analysis import TrialAnalysis, analyse
from logs.compare import RunComparison, compare_runs
from logs.errors import LogReadError, LogsError
from logs.topics import ESTIMATOR_POSE, TRUTH_POSE

logger = logging.getLogger(__name__)

HEADLINE_METRICS = (
    ("path_accuracy_pct", "path accuracy (% of driven)"),
    ("route_accuracy_pct", "path accuracy (% of route)"),
    ("obstacle_avoidance_success_pct", "obstacle-avoidance success (%)"),
    ("rollovers", "rollovers"),
    ("collisions", "collisions"),
    ("cross_track_error_rms_m", "cross-track error RMS (m)"),
    ("cross_track_error_max_m", "cross-track error max (m)"),
    ("energy_wh", "energy (Wh)"),
    ("energy_wh_per_m", "energy per metre (Wh/m)"),
    ("distance_m", "distance (m)"),
    ("duration_s", "duration (s)"),
    ("goal_reached", "goal reached"),
    ("final_distance_to_goal_m", "distance to goal at end (m, {source})"),
)
# What the trajectory metrics (distance, path accuracy, distance to goal...) were measured on
# (``TrialMetrics.trajectory_topic``): a simulation's ground truth, or a real run's own estimate.
TRAJECTORY_SOURCES = {TRUTH_POSE: "truth", ESTIMATOR_POSE: "estimate"}


class ReportError(LogsError):
    """No report could be written (no readable input, output folder unusable)."""


@dataclass
class ReportResult:
    html: Path
    markdown: Path
    json: Path
    runs: list[TrialAnalysis] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    comparisons: list[RunComparison] = field(default_factory=list)
    terrain_table: list[dict[str, Any]] = field(default_factory=list)


def expand_inputs(inputs: Sequence[str | Path]) -> tuple[list[Path], bool]:
    """Files as given, directories as their ``*.mcap`` files (sorted); and whether a directory was given."""
    files: list[Path] = []
    campaign = False
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            campaign = True
            files.extend(sorted(path.rglob("*.mcap")))
        else:
            files.append(path)
    return files, campaign


def write_report(inputs: Sequence[str | Path], out_dir: str | Path, *, plots: bool = True) -> ReportResult:
    files, campaign = expand_inputs(inputs)
    if not files:
        raise ReportError(f"no recordings found in {', '.join(map(str, inputs))}")
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ReportError(f"cannot create the report folder {out}: {err}") from err
    result = ReportResult(out / "report.html", out / "report.md", out / "report.json")
    for path in files:
        try:
            run = analyse(path)
        except LogReadError as err:
            result.failed[str(path)] = str(err)
            logger.warning("skipped %s: %s", path, err)
            continue
        if not any(run.counts.values()):
            # An empty file, or one cut before its first message: a report of it would be all blanks.
            result.failed[str(path)] = "holds no messages (cut before the first one?)"
            continue
        result.runs.append(run)
    result.comparisons = [compare_runs(a, b) for a, b in comparison_pairs(result.runs, campaign=campaign)]
    if campaign or len(result.runs) > 2:
        result.terrain_table = terrain_table(result.runs)
    document = _document(result)
    result.json.write_text(
        json.dumps(document, indent=2, sort_keys=True, default=str) + "\n", encoding="utf-8"
    )
    result.markdown.write_text(_markdown(result), encoding="utf-8")
    result.html.write_text(_html(result, plots), encoding="utf-8")
    return result


# --- tables -------------------------------------------------------------------------------------
def terrain_table(runs: Sequence[TrialAnalysis]) -> list[dict[str, Any]]:
    """Per terrain class (and per campaign variant, when the runs hold more than one): number of runs,
    mean path accuracy (of the driven distance and of the route)
    and avoidance success, total rollovers,
    mean Wh/m (means over the runs where the metric is known)."""
    split = len({_variant(run) for run in runs}) > 1
    groups: dict[tuple[str, str], list[TrialAnalysis]] = {}
    for run in runs:
        groups.setdefault((run.terrain_class, _variant(run) if split else ""), []).append(run)
    rows = []
    for (terrain, variant), members in sorted(groups.items()):
        metrics = [run.metrics for run in members]
        rows.append(
            {
                "terrain": terrain,
                **({"variant": variant or "n/a"} if split else {}),
                "runs": len(members),
                "path_accuracy_pct": _mean([m.path_accuracy_pct for m in metrics]),
                "route_accuracy_pct": _mean([m.route_accuracy_pct for m in metrics]),
                "obstacle_avoidance_success_pct": _mean([m.obstacle_avoidance_success_pct for m in metrics]),
                "rollovers": sum(m.rollovers or 0 for m in metrics),
                "goal_reached_pct": _mean([100.0 * bool(m.goal_reached) for m in metrics]),
                "final_distance_to_goal_m": _mean([m.final_distance_to_goal_m for m in metrics]),
                "energy_wh_per_m": _mean([m.energy_wh_per_m for m in metrics]),
            }
        )
    return rows


def comparison_pairs(
    runs: Sequence[TrialAnalysis], *, campaign: bool
) -> list[tuple[TrialAnalysis, TrialAnalysis]]:
    """Which runs are compared point by point.

    Files given one by one: the first against each other one (a sim run against the real runs, say). A
    campaign: only runs that differ in nothing but the variant (the same scenario and seed), the first
    variant against each other one; across terrains or seeds a point-by-point gap says nothing, and the
    per-terrain table compares those.
    """
    if not campaign:
        return [(runs[0], other) for other in runs[1:]]
    groups: dict[tuple[str, str], list[TrialAnalysis]] = {}
    for run in runs:
        scenario = run.metadata.get("scenario", {})
        groups.setdefault((scenario.get("name", run.path), scenario.get("seed", "")), []).append(run)
    return [
        (members[0], other)
        for members in groups.values()
        for other in members[1:]
        if _variant(other) != _variant(members[0])
    ]


def _variant(run: TrialAnalysis) -> str:
    """The campaign variant a trial ran (``trial.variant`` metadata; empty for a lone trial)."""
    return run.metadata.get("trial", {}).get("variant", "")


def _mean(values: Sequence[float | None]) -> float | None:
    known = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    return round(sum(known) / len(known), 6) if known else None


def _document(result: ReportResult) -> dict[str, Any]:
    return {
        "runs": [run.to_dict() for run in result.runs],
        "failed": result.failed,
        "comparisons": [comparison.to_dict() for comparison in result.comparisons],
        "terrain_table": result.terrain_table,
    }


def _fmt(value: Any) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.3f}" if math.isfinite(value) else "n/a"
    return str(value)


def _run_rows(run: TrialAnalysis) -> list[tuple[str, str]]:
    metrics = run.metrics.to_dict()
    topic = run.metrics.trajectory_topic
    source = TRAJECTORY_SOURCES.get(topic or "", "no trajectory")
    rows = [("trajectory from", f"{topic} ({source})" if topic else source)]
    rows += [(label.format(source=source), _fmt(metrics.get(key))) for key, label in HEADLINE_METRICS]
    rows += [(key.replace("_", " "), _fmt(value)) for key, value in run.figures.items()]
    rows.append(("can bus load from", run.can_load_source))
    return rows


def _count_rows(run: TrialAnalysis) -> list[tuple[str, str]]:
    """Messages per topic; the last row says where the counts come from."""
    rows = [(topic, str(n)) for topic, n in run.counts.items()]
    rows.append((f"({len(run.counts)} topics, from the {run.counts_source})", str(sum(run.counts.values()))))
    return rows


# --- Markdown -----------------------------------------------------------------------------------
def _md_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell.replace("|", "\\|") for cell in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def _markdown(result: ReportResult) -> str:
    parts = ["# Trial report\n"]
    for path, reason in result.failed.items():
        parts.append(f"**Not readable:** `{path}`: {reason}\n")
    for run in result.runs:
        parts.append(f"## {run.path}\n")
        parts.append(f"terrain: {run.terrain_class}\n")
        if run.missing:
            parts.append(f"**Partial report, missing:** {', '.join(run.missing)}\n")
        for problem in run.metrics.problems:
            parts.append(f"- problem: {problem}\n")
        parts.append(_md_table(("metric", "value"), _run_rows(run)))
        parts.append(_md_table(("topic", "messages"), _count_rows(run)))
    for comparison in result.comparisons:
        parts.append(f"## Comparison: A = {comparison.a}, B = {comparison.b}\n")
        parts.append(
            f"aligned over {len(comparison.s_m)} points every {comparison.step_m} m; position gap RMS "
            f"{_fmt(comparison.gap_rms_m)} m, max {_fmt(comparison.gap_max_m)} m\n"
        )
        rows = [
            (name, _fmt(v["a"]), _fmt(v["b"]), _fmt(v["difference"]))
            for name, v in comparison.metrics.items()
            if not v["same"]
        ]
        parts.append(_md_table(("metric", "A", "B", "B - A"), rows))
        diffs = [(d["key"] or "", d["a"] or "", d["b"] or "") for d in comparison.metadata_differences]
        parts.append(_md_table(("scenario / parameter", "A", "B"), diffs))
    if result.terrain_table:
        parts.append("## Per terrain\n")
        header = list(result.terrain_table[0])
        parts.append(_md_table(header, [[_fmt(row[key]) for key in header] for row in result.terrain_table]))
    return "\n".join(parts)


# --- HTML ---------------------------------------------------------------------------------------
_STYLE = (
    "body{font-family:sans-serif;max-width:62rem;margin:auto;padding:1rem}"
    "table{border-collapse:collapse;margin:.5rem 0}td,th{border:1px solid #ccc;padding:.2rem .5rem}"
    "td:nth-child(n+2){text-align:right}.warn{color:#a40}"
)


def _html_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _html(result: ReportResult, plots: bool) -> str:
    if plots:
        from logs import plots as plot  # matplotlib is slow to import: only when plots are drawn

    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>Trial report</title><style>{_STYLE}"]
    parts.append("</style></head><body><h1>Trial report</h1>")
    for path, reason in result.failed.items():
        parts.append(f"<p class='warn'><b>Not readable:</b> {html.escape(path)}: {html.escape(reason)}</p>")
    for run in result.runs:
        parts.append(f"<h2>{html.escape(run.path)}</h2><p>terrain: {html.escape(run.terrain_class)}</p>")
        if run.missing:
            parts.append(
                f"<p class='warn'><b>Partial report, missing:</b> {html.escape(', '.join(run.missing))}</p>"
            )
        for problem in run.metrics.problems:
            parts.append(f"<p class='warn'>{html.escape(problem)}</p>")
        parts.append(_html_table(("metric", "value"), _run_rows(run)))
        if plots:
            for draw in (plot.trajectory_svg, plot.cross_track_svg, plot.vehicle_svg, plot.innovations_svg):
                parts.append(f"<div>{draw(run)}</div>")
        parts.append(_html_table(("topic", "messages"), _count_rows(run)))
    for comparison in result.comparisons:
        parts.append(
            f"<h2>Comparison</h2><p>A = {html.escape(comparison.a)}<br>B = {html.escape(comparison.b)}</p>"
        )
        parts.append(
            f"<p>position gap RMS {_fmt(comparison.gap_rms_m)} m, max {_fmt(comparison.gap_max_m)} m "
            f"over {len(comparison.s_m)} points</p>"
        )
        rows = [
            (name, _fmt(v["a"]), _fmt(v["b"]), _fmt(v["difference"]))
            for name, v in comparison.metrics.items()
        ]
        parts.append(_html_table(("metric", "A", "B", "B - A"), rows))
        diffs = [(d["key"] or "", d["a"] or "", d["b"] or "") for d in comparison.metadata_differences]
        parts.append(_html_table(("scenario / parameter", "A", "B"), diffs))
        if plots and comparison.s_m:
            parts.append(f"<div>{plot.comparison_svg(comparison)}</div>")
    if result.terrain_table:
        header = list(result.terrain_table[0])
        parts.append("<h2>Per terrain</h2>")
        parts.append(
            _html_table(header, [[_fmt(row[key]) for key in header] for row in result.terrain_table])
        )
    parts.append("</body></html>\n")
    return "".join(parts)
