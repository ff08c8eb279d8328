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
    print_figures(console, figures, scenario.name, args.repeats)
    return 0


# Lockstep runs further apart than this (slowest over fastest) get a note under the table: on a shared VM the
# host's speed moves minute to minute, and a reader should know the median met a slow stretch.
UNSTEADY_SPREAD = 1.2


def unsteady_note(lockstep_runs: list[float], probe_runs: list[float]) -> str:
    """A note when the lockstep runs spread past ``UNSTEADY_SPREAD``, with the host probe's spread beside
    theirs (the same fixed work each round: if it spread too, the host's speed moved); "" when steady."""
    if len(lockstep_runs) < 2 or max(lockstep_runs) <= UNSTEADY_SPREAD * min(lockstep_runs):
        return ""
    note = (
        f"note: the lockstep runs took {min(lockstep_runs):.2f} to {max(lockstep_runs):.2f} s, "
        f"{_apart_pct(lockstep_runs):.0f} % apart"
    )
    if len(probe_runs) > 1:
        note += (
            f"; a fixed Python workload timed in each round took {1e3 * min(probe_runs):.0f} to "
            f"{1e3 * max(probe_runs):.0f} ms, {_apart_pct(probe_runs):.0f} % apart"
        )
    return note + ". On a busy or shared host, rerun when it is idle for a steady figure."


def _apart_pct(runs: list[float]) -> float:
    return 100.0 * (max(runs) / min(runs) - 1.0)


def print_figures(console: Console, figures: dict[str, Any], scenario_name: str, repeats: int) -> None:
    """The bench's figures as two tables and a summary line, readable at 80 columns (a CI log, a pipe).

    Figures never wrap or get cut: the labels wrap instead."""
    goal = figures["goal_real_time_factor"]
    peers = RichTable(
        title=f"rover bench hil: {scenario_name}, {figures['simulated_s']} s simulated, "
        f"median of {repeats} interleaved run(s)"
    )
    peers.add_column("peer / baseline", ratio=1, min_width=20)
    # Short headers, the caption spells them out: at 80 columns long ones squeezed the figures.
    peers.caption = "x real time: simulated s / wall s; CPU x: / CPU s; runs: fastest-slowest, s"
    for header in ("wall s", "x real time", "CPU x", "of goal", "runs"):
        peers.add_column(header, justify="right", no_wrap=True)
    for name, factor in figures["real_time_factor"].items():
        runs = figures["runs_wall_s"][name] or [figures["wall_s"][name]]  # a single run keeps no list
        peers.add_row(
            name,
            f"{figures['wall_s'][name]:.2f}",
            f"{factor:.1f}x",
            f"{figures['cpu_real_time_factor'][name]:.1f}x",
            f"{100.0 * factor / goal:.0f} %",
            f"{min(runs):.2f}-{max(runs):.2f}" if len(runs) > 1 else f"{runs[0]:.2f}",
        )
    for name, (low, high) in figures["named_baselines"].items():
        span = f"<= {high:.0f}x" if low == 0 else f"{low:.0f}-{high:.0f}x"
        peers.add_row(f"[dim]{name}, measured elsewhere[/dim]", "", f"[dim]{span}[/dim]", "", "", "")
    peers.add_row("[bold]goal[/bold]", "", f"[bold]{goal:.0f}x[/bold]", "", "100 %", "")
    console.print(peers)
    note = unsteady_note(figures["runs_wall_s"].get("lockstep", []), figures.get("host_probe_s", []))
    if note:
        console.print(note)
    breakdown = RichTable(title="per component (instrumented run, exclusive time)")
    breakdown.add_column("component", ratio=1)
    for header in ("s", "%", "calls", "us/call"):
        breakdown.add_column(header, justify="right", no_wrap=True)
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
    python = figures.get("python")
    if python:
        console.print(
            f"{python['implementation']} {python['version']} ({python['executable']}, {python['compiler']}): "
            "how the interpreter was built moves every figure (docs/hil.md)"
        )


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
