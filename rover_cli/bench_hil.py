"""``rover bench hil``: real-time factor of a full lockstep trial against its peers, with a breakdown."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table as RichTable

from logs.settings import ConfigError
from logs.sink import MessageSink
from rover_cli.errors import print_error

DEFAULT_SCENARIO = Path("scenarios/default.toml")


def register(commands: Any) -> None:
    bench = commands.add_parser("hil", help="real-time factor of a full lockstep HIL trial, per component")
    bench.add_argument("--scenario", type=Path, default=DEFAULT_SCENARIO, help="scenario TOML file")
    bench.add_argument("--config", type=Path, default=None, help="rover config TOML (default: built-in)")
    bench.add_argument("--no-zenoh", action="store_true", help="do not publish telemetry on Zenoh")
    bench.add_argument("--all-cores", action="store_true", help="do not pin the benchmark to one core")
    bench.add_argument(
        "--repeats",
        type=int,
        # Five: on a shared VM single runs of the same code differ by up to half, and a median of three
        # moved with each slow run.
        default=5,
        help="time each peer this many times, interleaved, and report the median (default 5)",
    )
    bench.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    bench.set_defaults(handler=run_bench_command)


def run_bench_command(args: argparse.Namespace) -> int:
    from hil.bench import run_bench
    from hil.scenario import load_scenario
    from logs.telemetry import ZenohSettings, ZenohTelemetry, open_session
    from logs.telemetry_station import rate_limited
    from rover_cli.hil_commands import load_config

    console = Console()
    try:
        scenario = load_scenario(args.scenario)
        config = load_config(args.config)
    except ConfigError as err:
        print_error(console, err)
        return 2

    # Every run's Zenoh stream, in order: the last is the instrumented run's, whose counts are reported.
    streams: list[ZenohTelemetry] = []

    def telemetry_factory() -> tuple[MessageSink | None, Callable[[], None]]:
        if args.no_zenoh:
            return None, lambda: None
        # Everything recorded includes Zenoh: on even if the config leaves it off, loopback only,
        # multicast scouting off.
        settings = config.zenoh if config.zenoh.enabled else ZenohSettings(enabled=True)
        session = open_session(settings)
        telemetry = ZenohTelemetry(session, config.rover_id)
        streams.append(telemetry)

        def close() -> None:
            telemetry.close()
            session.close()

        # As `rover hil trial` publishes: thinned to the config's [zenoh.rates] (the MCAP keeps everything).
        return rate_limited(telemetry, config.zenoh.rates_hz), close

    if args.repeats < 1:
        console.print(f"[red]error:[/red] --repeats must be >= 1, got {args.repeats}")
        return 2
    report = run_bench(
        scenario,
        config,
        telemetry_factory=telemetry_factory,
        one_core=not args.all_cores,
        repeats=args.repeats,
    )
    figures = report.as_dict()
    if streams:
        # With no subscriber, a topic's messages are counted, not put (ZenohTelemetry.unheard): say so.
        figures["zenoh_instrumented_run"] = {"put": streams[-1].published, "unheard": streams[-1].unheard}
    if args.json:
        print(json.dumps(figures, indent=2))
        return 0
    goal = figures["goal_real_time_factor"]
    peers = RichTable(
        title=f"rover bench hil: {scenario.name}, {figures['simulated_s']} s simulated, "
        f"median of {args.repeats} interleaved run(s)"
    )
    peers.add_column("peer / baseline", no_wrap=True)
    peers.add_column("wall s", justify="right")
    peers.add_column("real-time factor", justify="right")
    peers.add_column("CPU s", justify="right")
    peers.add_column("on CPU time", justify="right")
    peers.add_column("of goal", justify="right", no_wrap=True)
    peers.add_column("wall s of each run", justify="right")
    for name, factor in figures["real_time_factor"].items():
        peers.add_row(
            name,
            f"{figures['wall_s'][name]:.2f}",
            f"{factor:.1f}x",
            f"{figures['cpu_s'][name]:.2f}",
            f"{figures['cpu_real_time_factor'][name]:.1f}x",
            f"{100.0 * factor / goal:.0f} %",
            " ".join(f"{w:.2f}" for w in figures["runs_wall_s"][name]),
        )
    for name, (low, high) in figures["named_baselines"].items():
        span = f"<= {high:.0f}x" if low == 0 else f"{low:.0f}-{high:.0f}x"
        peers.add_row(f"[dim]{name}[/dim]", "", f"[dim]{span}[/dim]", "", "", "[dim]elsewhere[/dim]", "")
    peers.add_row("[bold]goal[/bold]", "", f"[bold]{goal:.0f}x[/bold]", "", "", "100 %", "")
    console.print(peers)
    breakdown = RichTable(title="per component (instrumented run, exclusive time)")
    breakdown.add_column("component", no_wrap=True)
    breakdown.add_column("s", justify="right")
    breakdown.add_column("%", justify="right")
    breakdown.add_column("calls", justify="right")
    breakdown.add_column("us/call", justify="right")
    for entry in figures["breakdown"].values():
        per_call = 1e6 * entry["seconds"] / entry["calls"] if entry["calls"] else 0.0
        breakdown.add_row(
            entry["what"],
            f"{entry['seconds']:.3f}",
            f"{entry['share_pct']:.1f}",
            str(entry["calls"]),
            f"{per_call:.1f}",
        )
    console.print(breakdown)
    console.print(
        f"metrics from the MCAP afterwards: {figures['metrics_from_mcap_s']:.3f} s; "
        f"instrumented run {figures['instrumented_wall_s']:.2f} s wall (timers add overhead); "
        f"untimed warm-up {figures['warmup_wall_s']:.2f} s; "
        f"pinned to CPU {figures['cpu']}; Zenoh {_zenoh_line(figures)}"
    )
    return 0


def _zenoh_line(figures: dict[str, Any]) -> str:
    if not figures["zenoh"]:
        return "off"
    counts = figures.get("zenoh_instrumented_run")
    if counts is None:
        return "on"
    return (
        f"on ({counts['put']} messages put, {counts['unheard']} counted but not put: no subscriber "
        "matched their topic)"
    )
