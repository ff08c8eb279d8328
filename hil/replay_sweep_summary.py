"""A sweep's summary as files beside its replays: ``sweep.json`` (every row and replay, for scripts) and
``sweep.md`` (the rows as a table, for people), as a campaign writes its summary tables."""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path
from typing import Any

from hil.replay_sweep import SweepResult

SUMMARY_JSON = "sweep.json"
SUMMARY_MARKDOWN = "sweep.md"


def sweep_document(result: SweepResult) -> dict[str, Any]:
    """The sweep as plain JSON data; a figure that is not finite (a comparison that could not be made) is
    null, as JSON has no infinity."""
    return _finite_or_null(
        {
            "rows": [asdict(row) for row in result.rows],
            "replays": [
                {
                    "recording": str(r.recording),
                    "config": r.config,
                    "replay": str(r.result.out_path),
                    "position_error_rms_m": r.figures.position_error_rms.replayed,
                    "recorded_position_error_rms_m": r.figures.position_error_rms.recorded,
                    "estimate_shift_rms_m": r.figures.estimate_shift_rms_m,
                    "wheel_commands_differing": r.result.wheel_commands_differing,
                    "wheel_commands_compared": r.result.wheel_commands_compared,
                    "wheel_speed_difference_max_mps": r.result.wheel_speed_difference_max_mps,
                    "partial": r.result.partial,
                }
                for r in result.replays
            ],
            "failed": result.failed,
        }
    )


def write_sweep_summary(result: SweepResult, out_dir: Path) -> tuple[Path, Path]:
    """Write ``sweep.json`` and ``sweep.md`` into ``out_dir``; returns their paths (Markdown first)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    json_path, markdown_path = out_dir / SUMMARY_JSON, out_dir / SUMMARY_MARKDOWN
    json_path.write_text(json.dumps(sweep_document(result), indent=2) + "\n", encoding="utf-8")
    markdown_path.write_text(_markdown(result), encoding="utf-8")
    return markdown_path, json_path


def _markdown(result: SweepResult) -> str:
    lines = [
        "# Replay sweep",
        "",
        "Means over the runs each config replayed; errors against the truth (the recordings' own in",
        "brackets); shift: from the recorded estimate; commands: wheel commands that differ from the",
        "recording's.",
        "",
        "| config | runs (with truth) | position error RMS, m | position error max, m | yaw error RMS, rad "
        "| estimate shift RMS, m | commands differing (max m/s) |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in result.rows:
        lines.append(
            f"| {row.config} | {row.recordings} ({row.with_truth}) "
            f"| {_cell(row.error_rms_mean_m)} ({_cell(row.recorded_error_rms_mean_m)}) "
            f"| {_cell(row.error_max_m)} | {_cell(row.yaw_error_rms_mean_rad)} "
            f"| {_cell(row.shift_rms_mean_m)} "
            f"| {row.wheel_commands_differing_pct:.1f} % ({_cell(row.wheel_speed_difference_max_mps, 3)}) |"
        )
    if result.failed:
        lines += ["", "Left out of every row:", ""]
        lines += [f"- `{recording}`: {why}" for recording, why in result.failed.items()]
    return "\n".join(lines) + "\n"


def _cell(value: float | None, digits: int = 4) -> str:
    return "n/a" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def _finite_or_null(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: _finite_or_null(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_finite_or_null(item) for item in value]
    return value
