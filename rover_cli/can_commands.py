"""``rover can ...``: tools for the CAN side of the rover (recorded frames out to CAN log files)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any


def register(families: Any) -> None:
    can_family = families.add_parser("can", help="CAN tools: export recorded frames to candump logs")
    commands = can_family.add_subparsers(dest="command", required=True, metavar="SUBCOMMAND")
    export = commands.add_parser(
        "export",
        help="write a recording's can/frames as a candump log (.log) or .asc/.blf/.trc/.csv by suffix",
    )
    export.add_argument("trial", type=Path, help="the recording (trial.mcap)")
    export.add_argument("out", type=Path, help="the CAN log to write; the suffix picks the format")
    export.add_argument("--channel", default="can0", help="interface name written per frame (default can0)")
    export.add_argument("--json", action="store_true", help="print the export figures as one JSON object")
    export.set_defaults(handler=export_command)


def export_command(args: argparse.Namespace) -> int:
    """Exit 0: every frame exported; 1: a log was written, but without some records (skipped, error frames
    the format has no line for, or the recording was cut short or damaged: stderr says where); 2: bad
    input, no log written."""
    from firmware_bridge.can_export import export_can_log
    from firmware_bridge.errors import BridgeError
    from logs.read_stop import partial_notice

    try:
        stats = export_can_log(args.trial, args.out, channel=args.channel)
    except BridgeError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps({"out": str(args.out), **stats.as_dict()}))
    else:
        errors = f", {stats.error_frames} of them error frames" if stats.error_frames else ""
        if stats.error_frames_dropped:
            dropped = stats.error_frames_dropped
            errors += f"; {dropped} error frames left out (the format has no line for them)"
        figures = (
            f"{stats.frames} frames ({stats.tx} tx, {stats.rx} rx{errors}), {stats.rejected} records skipped"
        )
        print(f"{args.out}: {figures}")
        if stats.wall_clock_start is not None:
            print(f"dated by the recording's wall clock: first frame at {stats.wall_clock_start}")
        elif stats.frames:
            print("no wall-clock start in the recording: its own times (.asc/.trc/.blf dated at export)")
    if stats.stop is not None:
        kept = f"wrote the {stats.frames} frames before it to {args.out}"
        print(f"rover can export: {partial_notice(args.trial, stats.stop, kept)}", file=sys.stderr)
    return 1 if stats.rejected or stats.error_frames_dropped or stats.stop is not None else 0
