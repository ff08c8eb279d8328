"""``rover logs replay``: a recording's inputs through the onboard stack again, under a config.

The replay itself is ``hil.replay``; the figures it prints, ``hil.replay_figures``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table as RichTable

from hil.campaign_workers import MAX_WORKERS
from logs.errors import LogsError
from logs.settings import ConfigError
from rover_cli.arg_types import bounded_int
from rover_cli.errors import print_error
from rover_cli.replay_sweep_command import fmt, sweep_command

if TYPE_CHECKING:
    from hil.replay import ReplayResult


def register(commands: Any) -> None:
    replay = commands.add_parser(
        "replay",
        help="feed recordings' inputs to the onboard stack again under one or more configs; write what it "
        "did and compare the configs",
    )
    replay.add_argument(
        "inputs",
        type=Path,
        nargs="+",
        help="a lockstep trial's or `rover run`'s recording; several, or folders of them (a campaign's)",
    )
    replay.add_argument(
        "--config",
        type=Path,
        action="append",
        required=True,
        help="a rover config to replay under; give it again for each config to compare",
    )
    replay.add_argument(
        "--scenario",
        type=Path,
        default=None,
        help="a lockstep trial's scenario (default: the one attached to each recording)",
    )
    replay.add_argument(
        "--out",
        type=Path,
        required=True,
        help="the new recording (must not exist); with several recordings or configs, a folder for them",
    )
    replay.add_argument(
        "--workers",
        type=bounded_int(0, MAX_WORKERS, "0: one per core"),
        default=0,
        help="with several recordings: worker processes, 0 (default) one per core",
    )
    replay.add_argument("--json", action="store_true", help="print the result as one JSON object")
    replay.set_defaults(handler=replay_command)


def replay_command(args: argparse.Namespace) -> int:
    """One recording under one config. Exit 0: replayed whole; 1: replayed, but the recording was cut short
    or some of its inputs could not be fed (each named in the log); 2: bad input, nothing replayed."""
    from hil.replay import replay_recording
    from hil.replay_figures import replay_figures
    from hil.scenario import load_scenario
    from logs.warn_once import each_message_once
    from rover_cli.hil_commands import load_config

    single = len(args.inputs) == 1 and not args.inputs[0].is_dir() and len(args.config) == 1
    if not single:
        return sweep_command(args)
    console = Console()
    recording, config_path = args.inputs[0], args.config[0]
    try:
        config = load_config(config_path)
        scenario = None if args.scenario is None else load_scenario(args.scenario)
        # One notice of a cut or damaged recording, not one per pass over it.
        with (
            each_message_once("logs.reader"),
            console.status(f"replaying {escape(str(recording))} ...") as status,
        ):
            result = replay_recording(
                recording,
                config,
                args.out,
                scenario=scenario,
                on_progress=lambda t_s: status.update(f"replaying {escape(str(recording))}: {t_s:.0f} s"),
            )
            status.update("comparing the estimates ...")
            figures = replay_figures(recording, args.out)
    except (ConfigError, LogsError) as err:
        print_error(console, err)
        return 2
    code = 1 if result.partial else 0
    if args.json:
        document = {
            "recording": str(recording),
            "replay": str(result.out_path),
            "source_mode": result.source_mode,
            "ticks": result.ticks,
            "ticks_skipped": result.ticks_skipped,
            "ingests": result.ingests,
            "inputs": {
                "mavlink_frames": result.mavlink_frames,
                "can_frames": result.can_frames,
                "can_error_frames": result.can_error_frames,
                "obstacle_records": result.obstacle_records,
                "ground_commands": result.ground_commands,
                "rejected": result.rejected_inputs,
            },
            "can_sends_refused": result.can_sends_refused,
            "copied_messages": result.copied_messages,
            "wheel_commands_compared": result.wheel_commands_compared,
            "wheel_commands_differing": result.wheel_commands_differing,
            "first_difference_s": result.first_difference_s,
            "wheel_speed_difference_max_mps": result.wheel_speed_difference_max_mps,
            "truncated": result.truncated,
            "config_changes": [
                {"key": key, "recorded": old, "replayed": new} for key, old, new in result.config_changes
            ],
            "figures": {f.label: {"recorded": f.recorded, "replayed": f.replayed} for f in figures.figures},
            "estimate_shift_rms_m": figures.estimate_shift_rms_m,
            "estimate_shift_max_m": figures.estimate_shift_max_m,
        }
        console.print_json(json.dumps(document))
        return code
    error_frames = _error_frames_note(result)
    console.print(
        f"replayed {result.ticks} ticks of {escape(str(recording))} ({result.source_mode}): "
        f"{result.mavlink_frames} MAVLink frames, {result.can_frames} CAN frames{error_frames}, "
        f"{result.obstacle_records} obstacle records and {result.ground_commands} ground commands fed; "
        f"{result.copied_messages} messages of the rest of the run (truth, the simulator's log) copied",
        soft_wrap=True,
    )
    if result.config_changes:
        changes = RichTable(title="config: recorded -> replayed")
        for column in ("key", "recorded", "replayed"):
            changes.add_column(column, overflow="fold")
        for key, old, new in result.config_changes:
            changes.add_row(escape(key), escape(old), escape(new))
        console.print(changes)
    else:
        console.print("config: the same values as the recording's")
    table = RichTable(title="estimator")
    for column in ("figure", "recorded", "replayed"):
        table.add_column(column, justify="left" if column == "figure" else "right", overflow="fold")
    for figure in figures.figures:
        table.add_row(figure.label, fmt(figure.recorded), fmt(figure.replayed))
    table.add_row(
        "position shift from the recorded estimate (m, RMS / max)",
        "",
        f"{fmt(figures.estimate_shift_rms_m)} / {fmt(figures.estimate_shift_max_m)}",
    )
    console.print(table)
    first = (
        ""
        if result.first_difference_s is None
        else f", the first at {result.first_difference_s:.2f} s, by up to "
        f"{result.wheel_speed_difference_max_mps:.4f} m/s a wheel"
    )
    console.print(
        f"wheel commands differing from the recording's: {result.wheel_commands_differing} of "
        f"{result.wheel_commands_compared} ticks{first} (open loop: the recorded motion does not answer them)"
    )
    if result.truncated:
        console.print("[yellow]the recording was cut short or damaged[/yellow]: replayed up to there")
    if result.rejected_inputs:
        console.print(
            f"[yellow]{result.rejected_inputs} input records not fed[/yellow] "
            "(unreadable or malformed; each named in the log)"
        )
    if result.ticks_skipped:
        console.print(
            f"[yellow]{result.ticks_skipped} ticks skipped[/yellow]: their navigator/state went back in time"
        )
    console.print(f"replay: {escape(str(result.out_path))}")
    return code


def _error_frames_note(result: ReplayResult) -> str:
    """The CAN error frames among the frames fed, and the sends a replayed bus-off refused, if any."""
    if not result.can_error_frames:
        return ""
    refused = (
        f"; the replayed bus-off refused {result.can_sends_refused} sends" if result.can_sends_refused else ""
    )
    return f" ({result.can_error_frames} of them error frames{refused})"
