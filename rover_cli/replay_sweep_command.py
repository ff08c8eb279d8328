"""``rover logs replay`` with several recordings (or folders of them) or several configs: one table, a row
a config (``hil.replay_sweep``)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.table import Table as RichTable

from logs.errors import LogsError
from logs.settings import ConfigError
from rover_cli.errors import print_error
from rover_cli.progress import job_progress


def sweep_command(args: argparse.Namespace) -> int:
    """Exit 0: every recording replayed whole under every config; 1: some left out (each named) or
    replayed only in part; 2: bad input (a config or the scenario does not load, no recording found)."""
    from hil.campaign_workers import resolved_workers
    from hil.replay_sweep import SweepConfig, replay_sweep, sweep_names
    from hil.replay_sweep_summary import sweep_document, write_sweep_summary
    from hil.scenario import load_scenario
    from rover_cli.hil_commands import load_config

    console = Console()
    try:
        configs = [
            SweepConfig(name, load_config(path))
            for name, path in zip(sweep_names(args.config), args.config, strict=True)
        ]
        scenario = None if args.scenario is None else load_scenario(args.scenario)
    except ConfigError as err:
        print_error(console, err)
        return 2
    recordings = _recordings(args.inputs, args.out)
    if not recordings:
        print_error(console, f"no .mcap recording in {', '.join(str(p) for p in args.inputs)}")
        return 2
    if args.out.exists() and not args.out.is_dir():
        print_error(console, f"--out {args.out}: with several recordings or configs it must be a folder")
        return 2
    if args.out.is_dir() and any(args.out.rglob("*.mcap")):
        # Refused whole rather than every replay failing on a file it must not write over.
        print_error(
            console, f"--out {args.out} already holds recordings (an earlier sweep's?): give a new folder"
        )
        return 2
    with job_progress(console, transient=True) as progress:
        task = progress.add_task("replaying", total=len(recordings) * len(configs))
        try:
            result = replay_sweep(
                recordings,
                configs,
                args.out,
                scenario=scenario,
                workers=resolved_workers(args.workers),
                on_done=lambda _recording: progress.advance(task, len(configs)),
            )
        except LogsError as err:  # the output folder itself cannot be written
            print_error(console, err)
            return 2
    partial = any(r.result.partial for r in result.replays)
    code = 1 if result.failed or partial else 0
    markdown, json_path = write_sweep_summary(result, args.out)
    if args.json:
        document = sweep_document(result)
        console.print_json(json.dumps(document))
        return code
    table = RichTable(
        title=f"{len(recordings) - len(result.failed)} recordings replayed under each config",
        caption="means over the runs; errors against the truth; shift: from the recorded estimate",
    )
    columns = (
        "config",
        "runs (truth)",
        "position error RMS m (as recorded)",
        "position error max m",
        "yaw error RMS rad",
        "estimate shift RMS m",
        "commands differing (max m/s)",
    )
    for column in columns:
        table.add_column(column, justify="left" if column == "config" else "right", overflow="fold")
    for row in result.rows:
        table.add_row(
            escape(row.config),
            f"{row.recordings} ({row.with_truth})",
            f"{fmt(row.error_rms_mean_m)} ({fmt(row.recorded_error_rms_mean_m)})",
            fmt(row.error_max_m),
            fmt(row.yaw_error_rms_mean_rad),
            fmt(row.shift_rms_mean_m),
            f"{row.wheel_commands_differing_pct:.1f} % ({row.wheel_speed_difference_max_mps:.3f})",
        )
    console.print(table)
    for recording, why in result.failed.items():
        console.print(f"[yellow]left out[/yellow] {escape(recording)}: {escape(why)}", soft_wrap=True)
    if partial:
        console.print(
            "[yellow]some recordings were cut short or damaged, or had inputs or ticks skipped[/yellow] "
            "(see the log)"
        )
    console.print(f"replays: {escape(str(args.out))}")
    console.print(f"summary: {escape(str(markdown))}\n         {escape(str(json_path))}")
    return code


def fmt(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.4f}"


def _recordings(inputs: list[Path], out_dir: Path) -> list[Path]:
    """The files given, and every .mcap under each folder given (sorted), without the sweep's own output."""
    found: list[Path] = []
    out = out_dir.resolve()
    for path in inputs:
        candidates = sorted(path.rglob("*.mcap")) if path.is_dir() else [path]
        found.extend(c for c in candidates if out not in c.resolve().parents)
    return found
