"""``rover logs report``: a self-contained HTML report, plus the same content as Markdown and JSON.

Inputs are recordings and/or directories (a campaign: every ``*.mcap`` below it). Each recording gets its
metrics, figures and plots; the first run is compared with each other run (aligned by distance); with more
than two runs, or a directory, the per-terrain table of the paper's metrics is added. A recording that
cannot be read at all is listed with the reason and the report goes on; one with missing topics gets a
partial section that lists what is missing. A path given as a file that is no recording (missing, a TOML
scenario or config: ``logs.report_inputs``) is refused before anything is read, and with no input read
nothing is written. A real-time HIL run (``rover run``'s recording and
``rover hil peer``'s ground truth, two files) is one run: ``--truth`` once per rover recording, paired in
order (``given_pairs``), or the two files given alone (``realtime_pairs``), merged by log time
(``logs.paired_run``); two such runs are compared as two lockstep trials are.
"""

from __future__ import annotations

import html
import json
import logging
import math
import shlex
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from logs.analysis import TrialAnalysis, analyse
from logs.compare import RunComparison, compare_runs
from logs.errors import LogReadError, LogsError, RecordingDamaged
from logs.paired_run import misplaced_truths
from logs.reader import read_metadata
from logs.report_inputs import not_a_recording
from logs.run_modes import ROVER_RUN_MODE
from logs.topics import ESTIMATOR_POSE

logger = logging.getLogger(__name__)

# (metric, label); "{source}" is where the trajectory came from, "truth" or "estimate" (trajectory_topic):
# a figure from the estimate must say so, it is what the rover believed, not where it was.
HEADLINE_METRICS = (
    ("path_accuracy_pct", "path accuracy (% of driven, {source})"),
    ("route_accuracy_pct", "path accuracy (% of route, {source})"),
    ("obstacle_avoidance_success_pct", "obstacle-avoidance success (%, {source})"),
    ("closest_obstacle_m", "closest approach to an obstacle (m, centre to its edge, {source})"),
    ("rollovers", "rollovers"),
    ("collisions", "collisions"),
    ("cross_track_error_rms_m", "cross-track error RMS (m, rover's estimate)"),
    ("cross_track_error_max_m", "cross-track error max (m, rover's estimate)"),
    ("energy_wh", "energy (Wh, net)"),
    ("energy_regenerated_wh", "energy regenerated (Wh, braking, in the net)"),
    ("energy_wh_per_m", "energy per metre (Wh/m, {source} distance)"),
    ("distance_m", "distance (m, {source})"),
    ("duration_s", "duration (s)"),
    ("goal_reached", "goal reached (rover's estimate)"),
    ("final_distance_to_goal_m", "distance to goal at end (m, {source})"),
)
FIGURE_LABELS = {
    "estimator_position_error_rms_m": "estimator position error RMS (m, vs truth)",
    "estimator_position_error_max_m": "estimator position error max (m, vs truth)",
    "estimator_yaw_error_rms_rad": "estimator yaw error RMS (rad, vs truth)",
    "control_period_mean_ms": "control period mean (ms)",
    "control_period_p99_ms": "control period p99 (ms)",
    "control_period_max_ms": "control period max (ms)",
    "can_frames": "CAN frames recorded",
    "can_frames_recorded_pct": "CAN frames recorded (% of the link's count)",
    "can_frames_rejected": "CAN frames the link rejected (not ours, wrong length, undecodable)",
    "can_rounds_withheld": "CAN command rounds withheld (bus off)",
    "can_bitrate": "CAN bitrate (bit/s)",
    "can_bus_load_mean_pct": "CAN bus load mean (%)",
    "can_bus_load_peak_pct": "CAN bus load peak (%)",
    "mavlink_bad_frames": "MAVLink bad frames (bad CRC, header, truncated)",
    "mavlink_dropped_bytes": "MAVLink bytes dropped over the receive budget",
    "mavlink_commands_refused": "MAVLink commands refused by the signing check",
    "mavlink_scans_refused": "MAVLink OBSTACLE_DISTANCE scans refused (unreadable)",
    "mavlink_beams_refused": "MAVLink DISTANCE_SENSOR readings refused (unreadable)",
    "mavlink_mission_refused": "MAVLink mission operations refused",
    "mavlink_mission_timeouts": "MAVLink mission transfers abandoned (retries ran out)",
    "innovations_rejected": "estimator innovations rejected",
    "safety_warnings": "safety warnings",
    "safety_errors": "safety errors",
    "log_errors": "log errors",
    "unusable_messages": "unusable messages",
}
# The other metrics (comparisons list every one) and the per-terrain table's columns.
OTHER_METRIC_LABELS = {
    "trajectory_topic": "trajectory from",
    "path_tolerance_m": "path tolerance (m)",
    "route_length_m": "planned route length (m)",
    "encounter_margin_m": "encounter margin (m)",
    "obstacles_encountered": "obstacles encountered ({source})",
    "obstacles_avoided": "obstacles avoided ({source})",
    "closest_obstacle_id": "obstacle approached closest ({source})",
    "truncated": "recording cut short",
    "skipped_messages": "messages skipped",
}
TERRAIN_COLUMNS = {
    "campaign": "campaign (folder)",
    "terrain": "terrain",
    "terrain_class": "terrain class",
    "variant": "variant",
    "runs": "runs",
    "path_accuracy_pct": "path accuracy (% of driven, mean)",
    "route_accuracy_pct": "path accuracy (% of route, mean)",
    "obstacle_avoidance_success_pct": "obstacle-avoidance success (%, mean)",
    "rollovers": "rollovers (total)",
    "collisions": "collisions (total)",
    "goal_reached_pct": "goal reached (% of runs)",
    "final_distance_to_goal_m": "distance to goal at end (m, mean)",
    "energy_wh_per_m": "energy per metre (Wh/m, mean)",
}
# Shown with 4 significant digits: 3 decimals leave a Wh/m figure (~0.01) with one or two.
SIGNIFICANT_METRICS = frozenset({"energy_wh_per_m"})


class ReportError(LogsError):
    """No report could be written (no readable input, output folder unusable)."""


@dataclass
class ReportResult:
    html: Path
    markdown: Path
    json: Path
    runs: list[TrialAnalysis] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    damaged: list[str] = field(default_factory=list)  # failed with a damaged chunk: recover keeps the rest
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


def campaign_folders(inputs: Sequence[str | Path], files: Sequence[Path]) -> dict[str, str]:
    """Each file's directory as given, when several were: each is a campaign of its own (a campaign run
    before and after a change), kept apart in the tables and comparisons. Empty for one directory (or
    none): its runs are one campaign however its folders nest."""
    folders = [Path(item) for item in inputs if Path(item).is_dir()]
    if len(folders) < 2:
        return {}
    found = {}
    for path in files:
        # The first folder given that holds the file (for a folder given inside another one too).
        holder = next((folder for folder in folders if path.is_relative_to(folder)), None)
        if holder is not None:
            found[str(path)] = str(holder)
    return found


def write_report(
    inputs: Sequence[str | Path],
    out_dir: str | Path,
    *,
    plots: bool = True,
    truth: str | Path | Sequence[str | Path] | None = None,
) -> ReportResult:
    """``truth``: the peer's ground truth of each real-time HIL run (``--truth``), one per rover recording
    in ``inputs`` and paired with them in order (``given_pairs``); one path is the one-run case. Without
    it, a lone real-time pair among the files is found by ``realtime_pairs``.

    ``ReportError``, with nothing written, for a path given as a file that is no recording (missing, a
    TOML scenario, not MCAP) and when no input could be read."""
    refused = [why for item in inputs if not Path(item).is_dir() and (why := not_a_recording(Path(item)))]
    if refused:
        raise ReportError(
            "; ".join(refused) + ": give MCAP recordings (.mcap) or folders of them; nothing written"
        )
    files, campaign = expand_inputs(inputs)
    if not files:
        raise ReportError(f"no recordings found in {', '.join(map(str, inputs))}")
    truths = [Path(truth)] if isinstance(truth, str | Path) else [Path(t) for t in truth or ()]
    if truths:
        reads: list[tuple[Path, Path | None]] = list(given_pairs(inputs, files, truths))
    else:
        found = {} if campaign else realtime_pairs(files)
        reads = [(path, found.get(path)) for path in files if path not in found.values()]
    out = Path(out_dir)
    result = ReportResult(out / "report.html", out / "report.md", out / "report.json")
    for path, paired_truth in reads:
        try:
            run = analyse(path, truth=paired_truth)
        except LogReadError as err:
            result.failed[str(path)] = str(err)
            if isinstance(err, RecordingDamaged):
                result.damaged.append(str(path))
            logger.warning("skipped %s: %s", path, err)
            continue
        if not any(run.counts.values()):
            # An empty file, or one cut before its first message: a report of it would be all blanks.
            result.failed[str(path)] = (
                "holds no messages (cut short before its first chunk's end: nothing to report or recover)"
                if run.metrics.truncated
                else "holds no messages"
            )
            continue
        result.runs.append(run)
    if not result.runs:
        # A report of no run would be all "Not readable" lines: the error says the same, with nothing written.
        reasons = "; ".join(f"{path}: {why}" for path, why in result.failed.items())
        raise ReportError(
            f"no input could be read ({reasons}); {unreadable_advice(result.damaged)}; nothing written"
        )
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ReportError(f"cannot create the report folder {out}: {err}") from err
    folders = campaign_folders(inputs, files)
    if campaign:
        # A campaign's order (terrains, then variants, as in its file: the first variant is the
        # baseline); the sort is stable, so runs without that metadata keep the order they were given in.
        # Files given one by one keep the order given: the first is the baseline of the comparisons.
        # Several campaign folders: each folder's runs together, in the order the folders were given.
        rank = {folder: index for index, folder in enumerate(dict.fromkeys(folders.values()))}
        result.runs.sort(
            key=lambda run: (rank.get(folders.get(run.path, ""), len(rank)), *campaign_order(run))
        )
    pairs = comparison_pairs(result.runs, campaign=campaign, folders=folders)
    result.comparisons = [compare_runs(a, b) for a, b in pairs]
    if campaign or len(result.runs) > 2:
        result.terrain_table = terrain_table(result.runs, folders)
    document = _document(result)
    result.json.write_text(
        json.dumps(document, indent=2, sort_keys=True, default=str) + "\n", encoding="utf-8"
    )
    result.markdown.write_text(_markdown(result, plots), encoding="utf-8")
    result.html.write_text(_html(result, plots), encoding="utf-8")
    return result


def unreadable_advice(damaged: Sequence[str]) -> str:
    """What to run about the inputs that could not be read: doctor for any; recover only for those with a
    damaged chunk (a file cut short is reported up to the cut, and one cut before its first chunk's end
    holds no message for recover to keep)."""
    advice = "`rover logs doctor FILE` says what is wrong with a file"
    if damaged:
        advice += (
            f"; `rover logs recover FILE OUT` keeps every complete chunk of {', '.join(damaged)}, "
            "those after the damage too"
        )
    return advice


def given_pairs(
    inputs: Sequence[str | Path], files: Sequence[Path], truths: Sequence[Path]
) -> list[tuple[Path, Path]]:
    """Each rover recording given with its ``--truth``, in the order given. ``ReportError`` (nothing is
    reported) naming what does not pair: a directory among ``inputs``, a count that differs, a truth
    recorded while another of the rover recordings ran (``misplaced_truths``). A truth of no rover's run
    at all, or a lockstep trial given with one, is found by ``read_paired`` and said in that run's part of
    the report, as for one pair."""
    directories = [str(item) for item in inputs if Path(item).is_dir()]
    if directories:
        raise ReportError(
            f"--truth pairs with rover recordings given as files, in order; {', '.join(directories)} is a "
            "directory, whose files' order says nothing about which truth is whose: give each rover "
            "recording as a file, with its --truth"
        )
    if len(truths) != len(files):
        given = ", ".join(f"--truth {path}" for path in truths)
        raise ReportError(
            f"{given}: each --truth pairs with one rover recording (rover run's rover.mcap), in the order "
            f"given; {len(truths)} --truth and {len(files)} recordings given ({', '.join(map(str, files))})"
        )
    pairs = list(zip(files, truths, strict=True))
    misplaced = misplaced_truths(pairs) if len(pairs) > 1 else []
    if misplaced:
        raise ReportError(
            "; ".join(misplaced) + ": the --truth files pair with the rover recordings in the order given; "
            "give them in that order"
        )
    return pairs


def realtime_pairs(files: Sequence[Path]) -> dict[Path, Path]:
    """rover file -> truth file, when the files given one by one hold exactly one real-time HIL run: one
    ``rover run`` recording (metadata ``trial.mode`` = ``rover-run``) and one ``rover hil peer`` truth
    file (a ``peer`` metadata record), beside any other runs (a lockstep trial to compare with). With two
    of either, which goes with which is not guessed: each file is its own run (report each pair with
    ``--truth``)."""
    rovers, truths = [], []
    for path in files:
        try:
            # quiet: analyse reads the file next and says where it is cut, once
            metadata = read_metadata(path, warn_cut=False)
        except LogsError:
            continue  # unreadable: analyse says why, in its place in the report
        if "peer" in metadata:
            truths.append(path)
        elif metadata.get("trial", {}).get("mode") == ROVER_RUN_MODE:
            rovers.append(path)
    return {rovers[0]: truths[0]} if len(rovers) == 1 and len(truths) == 1 else {}


# --- tables -------------------------------------------------------------------------------------
_UNPLACED = 1 << 30  # runs without campaign metadata come after those with it


def campaign_order(run: TrialAnalysis) -> tuple[int, int]:
    """(terrain index, variant index) in the campaign file, from the ``trial`` metadata."""
    trial = run.metadata.get("trial", {})
    return _index(trial.get("terrain_index")), _index(trial.get("variant_index"))


def _index(text: str | None) -> int:
    try:
        return int(text) if text is not None else _UNPLACED
    except ValueError:
        return _UNPLACED


def terrain_of(run: TrialAnalysis) -> str:
    """The campaign terrain the run belongs to (``trial.terrain``), else its terrain class: two campaign
    terrains of one class (field-a and field-b, both sandy) are two rows, as in the campaign summary."""
    return run.metadata.get("trial", {}).get("terrain") or run.terrain_class


def terrain_table(
    runs: Sequence[TrialAnalysis], folders: Mapping[str, str] | None = None
) -> list[dict[str, Any]]:
    """Per campaign terrain (and per campaign variant, when the runs hold more than one), in the order the
    runs come (``campaign_order``): number of runs, mean path accuracy (of the driven distance and of the
    route) and avoidance success, total rollovers and collisions, mean Wh/m (means over the runs where
    the metric is known). ``folders`` (``campaign_folders``): with several campaign folders, per folder
    too, in a first column."""
    folders = folders or {}
    split = len({_variant(run) for run in runs}) > 1
    groups: dict[tuple[str, str, str], list[TrialAnalysis]] = {}
    for run in runs:
        key = (folders.get(run.path, ""), terrain_of(run), _variant(run) if split else "")
        groups.setdefault(key, []).append(run)
    rows = []
    for (folder, terrain, variant), members in groups.items():
        metrics = [run.metrics for run in members]
        collisions = [m.collisions for m in metrics if m.collisions is not None]
        rows.append(
            {
                **({"campaign": folder or "(files given)"} if folders else {}),
                "terrain": terrain,
                "terrain_class": members[0].terrain_class,
                **({"variant": variant or "n/a"} if split else {}),
                "runs": len(members),
                "path_accuracy_pct": _mean([m.path_accuracy_pct for m in metrics]),
                "route_accuracy_pct": _mean([m.route_accuracy_pct for m in metrics]),
                "obstacle_avoidance_success_pct": _mean([m.obstacle_avoidance_success_pct for m in metrics]),
                "rollovers": sum(m.rollovers or 0 for m in metrics),
                # unknown in real runs (no truth/contacts): the sum of the known, n/a when none is known
                "collisions": sum(collisions) if collisions else None,
                "goal_reached_pct": _mean([100.0 * bool(m.goal_reached) for m in metrics]),
                "final_distance_to_goal_m": _mean([m.final_distance_to_goal_m for m in metrics]),
                "energy_wh_per_m": _mean([m.energy_wh_per_m for m in metrics]),
            }
        )
    return rows


def comparison_pairs(
    runs: Sequence[TrialAnalysis], *, campaign: bool, folders: Mapping[str, str] | None = None
) -> list[tuple[TrialAnalysis, TrialAnalysis]]:
    """Which runs are compared point by point.

    Files given one by one: the first against each other one (a sim run against the real runs, say). A
    campaign: only runs that differ in nothing but the variant (the same campaign terrain, scenario and
    seed), the first variant against each other one; across terrains or seeds a point-by-point gap says
    nothing, and the per-terrain table compares those. The terrain counts apart from the scenario's name:
    two terrains' scenario files may share one (a copy with another map). Several campaign folders
    (``folders``): within each.
    """
    if not campaign:
        return [(runs[0], other) for other in runs[1:]]
    folders = folders or {}
    groups: dict[tuple[str, str, str, str], list[TrialAnalysis]] = {}
    for run in runs:
        scenario = run.metadata.get("scenario", {})
        place = (terrain_of(run), scenario.get("name", run.path), scenario.get("seed", ""))
        groups.setdefault((folders.get(run.path, ""), *place), []).append(run)
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


def _fmt(value: Any, key: str = "") -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        if not math.isfinite(value):
            return "n/a"
        return _significant(value) if key in SIGNIFICANT_METRICS else f"{value:.3f}"
    return str(value)


def _significant(value: float, digits: int = 4) -> str:
    """``value`` with ``digits`` significant digits, trailing zeros kept and never in scientific notation
    (``f"{v:.4g}"`` gave "0.025" beside "0.0249", and "9.7e-05" for their difference)."""
    if value == 0:
        return "0.000"
    # The exponent of the value as rounded: 0.099996 rounds up to 0.1000, not to "0.10000".
    rounded = float(f"{value:.{digits - 1}e}")
    decimals = max(0, digits - 1 - math.floor(math.log10(abs(rounded))))
    return f"{value:.{decimals}f}"


def metric_label(key: str, source: str) -> str:
    """The human label of a ``TrialMetrics`` field; ``source`` says where trajectory figures come from."""
    label = dict(HEADLINE_METRICS).get(key) or OTHER_METRIC_LABELS.get(key) or key.replace("_", " ")
    return label.format(source=source)


def _pair_source(comparison: RunComparison) -> str:
    a, b = _side_sources(comparison)
    return a if a == b else f"A {a}, B {b}"


def _side_sources(comparison: RunComparison) -> tuple[str, str]:
    """Whether A's and B's trajectories are their truth or their estimate."""
    topics = comparison.metrics.get("trajectory_topic", {})
    return _source_of_topic(topics.get("a")), _source_of_topic(topics.get("b"))


def _source_of_topic(topic: Any) -> str:
    return "estimate" if topic == ESTIMATOR_POSE else "truth"


def _terrain_rows(result: ReportResult) -> tuple[list[str], list[list[str]]]:
    keys = list(result.terrain_table[0])
    header = [TERRAIN_COLUMNS.get(key, key) for key in keys]
    return header, [[_fmt(row[key], key) for key in keys] for row in result.terrain_table]


def trajectory_source(run: TrialAnalysis) -> str:
    """ "truth" or "estimate": where the run's trajectory metrics come from."""
    return _source_of_topic(run.metrics.trajectory_topic)


def _run_rows(run: TrialAnalysis) -> list[tuple[str, str]]:
    metrics = run.metrics.to_dict()
    source = trajectory_source(run)
    rows = [(label.format(source=source), _fmt(metrics.get(key), key)) for key, label in HEADLINE_METRICS]
    rows += [
        (FIGURE_LABELS.get(key, key.replace("_", " ")), _fmt(value, key))
        for key, value in run.figures.items()
    ]
    rows.append(("CAN bus load from", run.can_load_source))
    return rows


def run_identity(run: TrialAnalysis) -> list[tuple[str, str]]:
    """What ran: scenario, seed, campaign terrain and variant, config source, mode, trajectory source."""
    scenario = run.metadata.get("scenario", {})
    trial = run.metadata.get("trial", {})
    return [
        ("scenario", scenario.get("name") or "n/a (not recorded)"),
        ("seed", scenario.get("seed") or "n/a"),
        ("terrain", f"{terrain_of(run)} (class {run.terrain_class})"),
        ("variant", trial.get("variant") or "n/a"),
        ("config", trial.get("config") or "n/a"),
        ("mode", trial.get("mode") or "n/a"),
        ("trajectory", f"{run.metrics.trajectory_topic or 'none'} ({trajectory_source(run)})"),
    ]


def _identity_text(run: TrialAnalysis) -> str:
    return "; ".join(f"{key}: {value}" for key, value in run_identity(run))


def _paired_text(run: TrialAnalysis) -> str:
    if not run.truth_merged:
        return (
            f"The ground truth {run.truth_path} was given (--truth) but not merged (the problem below says "
            f"why): this is the rover's {run.path} alone."
        )
    return (
        f"One real-time HIL run from two recordings, merged by log time (the OS monotonic clock both "
        f"stamp): the rover's {run.path} and the peer's ground truth {run.truth_path}."
    )


def _comparison_text(comparison: RunComparison) -> str:
    if comparison.not_comparable:
        return (
            "not compared point by point: the runs are of different scenarios ("
            + "; ".join(comparison.not_comparable)
            + "), so a position gap would mean nothing; per-run metrics above, differences below"
        )
    return (
        f"aligned by distance driven over {len(comparison.s_m)} points every {comparison.step_m} m; "
        f"position gap (to the other track within an along-track window) RMS {_fmt(comparison.gap_rms_m)} m, "
        f"max {_fmt(comparison.gap_max_m)} m"
    )


EVENTS_HEADER = ("t (s)", "severity", "kind", "detail")


def _event_rows(run: TrialAnalysis) -> list[tuple[str, str, str, str]]:
    """The run's safety/events, a row each (time from the recording's first message)."""
    return [(f"{e.t_s:.2f}", e.severity, e.kind, e.detail) for e in run.events]


def _events_title(run: TrialAnalysis) -> str:
    more = (
        f"; {run.events_unlisted} more not listed (`rover logs csv {shlex.quote(run.path)} --out DIR "
        f"--topics safety/events` has them all)"
        if run.events_unlisted
        else ""
    )
    return f"Events (safety/events: failsafes, modes, goals, what the rover learned){more}"


def _count_rows(run: TrialAnalysis) -> list[tuple[str, str]]:
    """Messages per topic; the last row says where the counts come from."""
    rows = [(topic, str(n)) for topic, n in run.counts.items()]
    rows.append((f"({len(run.counts)} topics, from the {run.counts_source})", str(sum(run.counts.values()))))
    return rows


# --- Markdown -----------------------------------------------------------------------------------
def _md_cell(text: str) -> str:
    """``text`` as one Markdown table cell that shows it as written: backslashes, pipes and HTML's
    characters escaped, a line break as ``<br>`` (a bare newline would end the row)."""
    text = text.replace("\\", "\\\\").replace("|", "\\|")
    text = text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    return text.replace("\r\n", "<br>").replace("\n", "<br>").replace("\r", "<br>")


def _md_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_md_cell(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


# The plots are SVG inside report.html; PNG copies for the Markdown would cost more than the SVG (the
# default trial's four: 1.1-1.4 s against 0.75-1.1 s, in a 3.7-4.7 s report), so the Markdown says where.
PLOTS_IN_HTML = (
    "Plots: in [report.html](report.html), beside this file (each run's trajectory, cross-track error, "
    "speed / current / stability margin and innovations; each comparison's position gap and speeds).\n"
)
NO_PLOTS = "No plots: written without them (`--no-plots`); report.html has the same tables.\n"


def _markdown(result: ReportResult, plots: bool) -> str:
    parts = ["# Trial report\n", PLOTS_IN_HTML if plots else NO_PLOTS]
    for path, reason in result.failed.items():
        parts.append(f"**Not readable:** `{path}`: {reason}\n")
    for run in result.runs:
        parts.append(f"## {run.path}\n")
        parts.append(f"{_identity_text(run)}\n")
        if run.truth_path:
            parts.append(f"{_paired_text(run)}\n")
            parts.append(_md_table(("part", "from"), run.sources))
        if run.missing:
            parts.append(f"**Partial report, missing:** {', '.join(run.missing)}\n")
        for problem in run.metrics.problems:
            parts.append(f"- problem: {problem}\n")
        parts.append(_md_table(("metric", "value"), _run_rows(run)))
        if run.events:
            parts.append(f"### {_events_title(run)}\n")
            parts.append(_md_table(EVENTS_HEADER, _event_rows(run)))
        parts.append(_md_table(("topic", "messages"), _count_rows(run)))
    for comparison in result.comparisons:
        parts.append(f"## Comparison: A = {comparison.a}, B = {comparison.b}\n")
        parts.append(f"{_comparison_text(comparison)}\n")
        source = _pair_source(comparison)
        rows = [
            (metric_label(name, source), _fmt(v["a"], name), _fmt(v["b"], name), _fmt(v["difference"], name))
            for name, v in comparison.metrics.items()
            if not v["same"]
        ]
        parts.append(_md_table(("metric", "A", "B", "B - A"), rows))
        diffs = [(d["key"] or "", d["a"] or "", d["b"] or "") for d in comparison.metadata_differences]
        parts.append(_md_table(("scenario / parameter", "A", "B"), diffs))
    if result.terrain_table:
        parts.append("## Per terrain\n")
        parts.append(_md_table(*_terrain_rows(result)))
    return "\n".join(parts)


# --- HTML ---------------------------------------------------------------------------------------
_STYLE = (
    "body{font-family:sans-serif;max-width:62rem;margin:auto;padding:1rem}"
    "table{border-collapse:collapse;margin:.5rem 0}td,th{border:1px solid #ccc;padding:.2rem .5rem}"
    "td:nth-child(n+2){text-align:right}.warn{color:#a40}"
    "table.text td{text-align:left;overflow-wrap:anywhere}"
)


def _html_table(header: Sequence[str], rows: Sequence[Sequence[str]], *, text: bool = False) -> str:
    """``text``: every column left-aligned (words, not figures)."""
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table{' class=text' if text else ''}><tr>{head}</tr>{body}</table>"


def _html(result: ReportResult, plots: bool) -> str:
    if plots:
        from logs import plots as plot  # matplotlib is slow to import: only when plots are drawn

    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>Trial report</title><style>{_STYLE}"]
    parts.append("</style></head><body><h1>Trial report</h1>")
    for path, reason in result.failed.items():
        parts.append(f"<p class='warn'><b>Not readable:</b> {html.escape(path)}: {html.escape(reason)}</p>")
    for run in result.runs:
        parts.append(f"<h2>{html.escape(run.path)}</h2><p>{html.escape(_identity_text(run))}</p>")
        if run.truth_path:
            parts.append(f"<p>{html.escape(_paired_text(run))}</p>")
            parts.append(_html_table(("part", "from"), run.sources))
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
        if run.events:
            parts.append(f"<h3>{html.escape(_events_title(run))}</h3>")
            parts.append(_html_table(EVENTS_HEADER, _event_rows(run), text=True))
        parts.append(_html_table(("topic", "messages"), _count_rows(run)))
    for comparison in result.comparisons:
        parts.append(
            f"<h2>Comparison</h2><p>A = {html.escape(comparison.a)}<br>B = {html.escape(comparison.b)}</p>"
        )
        warn = " class='warn'" if comparison.not_comparable else ""
        parts.append(f"<p{warn}>{html.escape(_comparison_text(comparison))}</p>")
        source = _pair_source(comparison)
        rows = [
            (metric_label(name, source), _fmt(v["a"], name), _fmt(v["b"], name), _fmt(v["difference"], name))
            for name, v in comparison.metrics.items()
        ]
        parts.append(_html_table(("metric", "A", "B", "B - A"), rows))
        diffs = [(d["key"] or "", d["a"] or "", d["b"] or "") for d in comparison.metadata_differences]
        parts.append(_html_table(("scenario / parameter", "A", "B"), diffs))
        if plots and comparison.s_m:
            source_a, source_b = _side_sources(comparison)
            svg = plot.comparison_svg(comparison, f"A ({source_a})", f"B ({source_b})")
            parts.append(f"<div>{svg}</div>")
    if result.terrain_table:
        parts.append("<h2>Per terrain</h2>")
        parts.append(_html_table(*_terrain_rows(result)))
    parts.append("</body></html>\n")
    return "".join(parts)
