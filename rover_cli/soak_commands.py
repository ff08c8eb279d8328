"""``rover hil soak``: minutes of real-time HIL with seeded faults; prints what was injected, seen and
recovered, memory, ticks and crashes (``hil.soak``). Run it under ``scripts/in-private-netns``."""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from hil.hardware_priority import PEER_FIFO_PRIORITY
from rover_cli.arg_types import fifo_priority, seed
from rover_cli.errors import print_error


def register(commands: Any) -> None:
    soak = commands.add_parser(
        "soak", help="real-time HIL (peer + rover run) for minutes with seeded faults; crash / memory report"
    )
    soak.add_argument("--minutes", type=float, default=10.0, help="how long to run (default 10)")
    soak.add_argument("--seed", type=seed, default=1, help="seed of the fault schedule")
    soak.add_argument("--out", type=Path, default=None, help="output directory (default: logs/trials/soak-*)")
    soak.add_argument("--rss-period", type=float, default=5.0, help="seconds between memory samples")
    soak.add_argument(
        "--warmup",
        type=float,
        default=20.0,
        help="seconds from the rover's first wheel command (the soak's time zero) to the first fault",
    )
    soak.add_argument("--can-interface", default="udp_multicast", help="udp_multicast (netns) or socketcan")
    soak.add_argument("--can-channel", default=None, help="e.g. vcan0 (default: a fresh multicast group)")
    soak.add_argument(
        "--peer-fifo",
        type=fifo_priority,
        default=PEER_FIFO_PRIORITY,
        help="run the simulated rover at this SCHED_FIFO priority, as timer-driven hardware (`rover hil "
        f"peer --fifo`; default {PEER_FIFO_PRIORITY}; 0: normal scheduling)",
    )
    soak.set_defaults(handler=run_soak_command)


def run_soak_command(args: argparse.Namespace) -> int:
    from hil.soak import SoakSettings, SoakSetupError, run_soak

    console = Console()
    if not args.minutes > 0 or not args.rss_period > 0 or args.warmup < 0:
        console.print("[red]error:[/red] --minutes and --rss-period must be > 0, --warmup >= 0")
        return 2
    out = args.out or Path("logs/trials") / time.strftime(f"soak-seed{args.seed}-%Y%m%d-%H%M%S")
    settings = SoakSettings(
        seconds=args.minutes * 60.0,
        seed=args.seed,
        out_dir=out,
        rss_period_s=args.rss_period,
        warmup_s=args.warmup,
        can_interface=args.can_interface,
        can_channel=args.can_channel,
        peer_fifo=args.peer_fifo,
    )
    try:
        with console.status(f"soaking for {args.minutes:g} min (seed {args.seed}) ..."):
            report = run_soak(settings)
    except SoakSetupError as err:
        print_error(console, err)
        return 2
    faults = Table(title=f"soak {args.minutes:g} min, seed {args.seed}: faults")
    for column in ("fault", "from s", "to s", "injected", "seen", "recovered", "evidence"):
        faults.add_column(column)
    for f in report.faults:
        faults.add_row(
            f.name,
            f"{f.start_s:.1f}",
            f"{f.end_s:.1f}",
            _yes(f.injected),
            _yes(f.seen),
            _yes(f.recovered),
            f.evidence,
        )
    console.print(faults)
    memory = Table(title="resident memory (MB)")
    for column in ("process", "start", "end", "max", "growth MB/min (after warm-up)"):
        memory.add_column(column)
    for m in report.memory:
        memory.add_row(
            m.name, _mb(m.start_mb), _mb(m.end_mb), _mb(m.max_mb), _mb(m.slope_mb_per_min, "{:+.3f}")
        )
    console.print(memory)
    first_tick = "never" if report.rover_first_tick_s is None else f"at {report.rover_first_tick_s:.1f} s"
    console.print(
        # The peer held its scenario until the rover's first wheel command: every time counts from it.
        "times in s from the rover's first wheel command; "
        f"rover's first tick {first_tick}; "
        f"ticks {report.ticks} (sensor {report.sensor_ticks}, deadline {report.deadline_ticks}), "
        f"overruns {report.overruns}; failsafes fired: {report.failsafe_events}"
    )
    peer = report.peer
    # Before the rover's first command the peer held its scenario: no rover drove on its steps yet.
    held = peer.stalls_before_start
    before_start = f", {held} of them before the rover's first command (not judged)" if held else ""
    console.print(
        f"peer ({report.peer_scheduling}): overruns {'unknown' if peer.overruns is None else peer.overruns}, "
        f"stalls {peer.stalls}{before_start} "
        f"({peer.dropped_sim_ms:.0f} ms of simulated time dropped), longest gap between steps "
        f"{_mb(peer.longest_step_gap_ms, '{:.0f} ms') if peer.longest_step_gap_ms is not None else 'unknown'}"
    )
    # A failsafe the host's stall of the peer accounts for is not the stack's (hil.soak_report).
    console.print(f"failsafes a stall of the peer explains: {len(report.stall_failsafes) or 'none'}")
    for failsafe in report.stall_failsafes:
        console.print(f"  - {failsafe}", markup=False, soft_wrap=True)
    unexplained = report.unexplained_failsafes
    console.print(f"failsafes no planned fault explains: {len(unexplained) or 'none'}")
    for failsafe in unexplained:
        console.print(f"  - {failsafe}", markup=False, soft_wrap=True)
    console.print(f"crashes: {', '.join(report.crashes) if report.crashes else 'none'}")
    console.print(f"{'[green]OK[/green]' if report.ok else '[red]NOT OK[/red]'}; report: {out / 'soak.json'}")
    for problem in report.problems:
        console.print(f"  - {problem}", markup=False, soft_wrap=True)
    return 0 if report.ok else 1


def _yes(value: bool) -> str:
    return "yes" if value else "[red]no[/red]"


def _mb(value: float, pattern: str = "{:.1f}") -> str:
    return "n/a" if not math.isfinite(value) else pattern.format(value)
