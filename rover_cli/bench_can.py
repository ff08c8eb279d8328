"""``rover bench can``: VESC frame rounds per second and latency on the virtual bus, and the bus load."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table as RichTable

from logs.settings import ConfigError
from rover_cli.arg_types import bounded_int
from rover_cli.errors import print_error

# Fewer frames than this measure the timer more than the codec; a smaller --rounds is refused, not rounded up.
MIN_ROUNDS = 200
MAX_ROUNDS = 10_000_000


def register(commands: Any) -> None:
    bench = commands.add_parser("can", help="CAN rounds/s, receive latency and bus load (virtual bus)")
    bench.add_argument(
        "--rounds",
        type=bounded_int(MIN_ROUNDS, MAX_ROUNDS),
        default=20_000,
        help=f"frames per measurement (default 20000, at least {MIN_ROUNDS})",
    )
    bench.add_argument(
        "--config",
        type=Path,
        default=None,
        help="rover config TOML: its [vesc] profile (a team's own dbc too), [can] rates (default: built-in)",
    )
    bench.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    bench.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from firmware_bridge.can_bench import run_can_bench  # imported when picked, like every benchmark
    from rover_cli.hil_commands import load_config

    console = Console()
    try:
        config = load_config(args.config)
    except ConfigError as err:
        print_error(console, err)
        return 2
    result = run_can_bench(args.rounds, config.vesc, config.can)
    if args.json:
        print(json.dumps(result.as_dict()))
        return 0
    table = RichTable(
        title=f"CAN rounds (encode -> send -> receive -> decode), {result.rounds} frames, DBC: {result.dbc}"
    )
    table.add_column("implementation")
    table.add_column("rounds/s", justify="right")
    table.add_column("µs/round", justify="right")
    for figures in [result.ours, *result.peers]:
        table.add_row(figures.name, f"{figures.rounds_per_s:,.0f}", f"{figures.us_per_round:.1f}")
    console.print(table)
    six = result.link_six_wheel_rounds_per_s
    console.print(f"CanLink six-wheel command rounds/s (recorded to a null sink): {six:,.0f}")
    p50, p99 = result.latency_p50_us, result.latency_p99_us
    console.print(f"receive latency on the virtual bus: p50 {p50:.1f} µs, p99 {p99:.1f} µs")
    load = result.bus_load
    console.print(
        f"\\[can] rates on {config.can.bitrate / 1e6:g} Mbit/s: {load.frames_per_s:,.0f} frames/s, "
        f"{load.load_pct_nominal:.1f} % "
        f"(no stuffing) to {load.load_pct_worst:.1f} % (worst-case stuffing)"
    )
    return 0
