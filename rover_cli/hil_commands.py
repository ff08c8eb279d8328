"""``rover hil ...``: lockstep trials on the simulator."""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.table import Table as RichTable

from hil.campaign_workers import MAX_WORKERS
from hil.peer_start import DEFAULT_TIMEOUT_S as DEFAULT_START_TIMEOUT_S
from logs.settings import ConfigError, parse_toml
from logs.sink import MessageSink
from navigator.config import RoverConfig, load_rover_config, rover_config_from_table
from rover_cli import soak_commands
from rover_cli.arg_types import bounded_int, fifo_priority, positive_seconds, seed
from rover_cli.errors import print_error
from rover_cli.process_age import process_age_s

if TYPE_CHECKING:
    from hil.campaign_runner import TrialOutcome
    from hil.trial import TrialResult

DEFAULT_TRIALS_DIR = Path("logs/trials")
# What `rover hil trial` writes into its --out: the recording, the metrics, and with --report the report
# (logs.report.write_report's three files). Any of them there already is an earlier trial's: refused.
# Spelled out rather than imported (hil.trial's TRIAL_MCAP, METRICS_JSON): the CLI imports hil only when a
# hil command runs (tests/system/test_cli_imports.py).
TRIAL_FILES = ("trial.mcap", "metrics.json", "report.html", "report.md", "report.json")


def register(families: Any) -> None:
    hil = families.add_parser("hil", help="hardware-in-the-loop simulation")
    commands = hil.add_subparsers(dest="command", required=True, metavar="SUBCOMMAND")
    trial = commands.add_parser("trial", help="run one lockstep HIL trial and report its metrics")
    trial.add_argument("scenario", type=Path, help="scenario TOML file")
    trial.add_argument("--seed", type=seed, default=None, help="random seed (default: the scenario's)")
    trial.add_argument("--config", type=Path, default=None, help="rover config TOML (default: built-in)")
    trial.add_argument("--out", type=Path, default=None, help="output directory (default: logs/trials/<run>)")
    trial.add_argument("--no-telemetry", action="store_true", help="do not publish on Zenoh")
    trial.add_argument(
        "--report", action="store_true", help="also write report.html/.md/.json next to the recording"
    )
    trial.set_defaults(handler=run_trial_command)
    campaign = commands.add_parser(
        "campaign", help="run terrains x variants x seeds on all cores; write the paper-style summary"
    )
    campaign.add_argument("campaign", type=Path, help="campaign TOML file")
    campaign.add_argument(
        "--out", type=Path, default=None, help="output directory (default: logs/trials/<name>)"
    )
    campaign.add_argument(
        "--workers",
        type=bounded_int(0, MAX_WORKERS, "0: one per core"),
        default=None,
        help="worker processes, 0: one per core (default: the file's `workers`)",
    )
    campaign.set_defaults(handler=run_campaign_command)
    _register_peer(commands)
    soak_commands.register(commands)


def _register_peer(commands: Any) -> None:
    peer = commands.add_parser(
        "peer", help="the simulated rover in real time, on a CAN bus and a MAVLink UDP port, for `rover run`"
    )
    peer.add_argument("scenario", type=Path, help="scenario TOML file")
    peer.add_argument("--seed", type=seed, default=None, help="random seed (default: the scenario's)")
    peer.add_argument("--config", type=Path, default=None, help="rover config TOML (default: built-in)")
    peer.add_argument("--can-interface", default=None, help="python-can interface (default: the config's)")
    peer.add_argument(
        "--can-channel", default=None, help="CAN channel, e.g. vcan0 or a 239.x.y.z udp_multicast group"
    )
    peer.add_argument(
        "--mavlink", default="udpin:127.0.0.1:0", help="where the autopilot listens (port 0: the OS picks)"
    )
    peer.add_argument("--port-file", type=Path, default=None, help="write the bound MAVLink UDP port here")
    peer.add_argument("--status-file", type=Path, default=None, help="keep the body's state here (JSON)")
    peer.add_argument(
        "--duration",
        type=positive_seconds,
        default=None,
        help="stop this many seconds after the peer started (with --start-on-command too)",
    )
    peer.add_argument(
        "--start-on-command",
        action="store_true",
        help="hold the scenario (rover parked at its start; faults and moving obstacles not counting; "
        "sensors and wheel status sent as usual) until the rover commands its wheels on CAN (a second round "
        "of commands within the controllers' timeout), and count the scenario's time from its first "
        "command (default: from the peer's start)",
    )
    peer.add_argument(
        "--start-timeout",
        type=positive_seconds,
        default=None,
        help="with --start-on-command: stop (exit 1) if the rover did not command within this many seconds "
        f"of the peer being ready (default {DEFAULT_START_TIMEOUT_S:g})",
    )
    peer.add_argument("--out", type=Path, default=None, help="output directory (default: logs/trials/<run>)")
    peer.add_argument(
        "--fifo",
        type=fifo_priority,
        default=0,
        help="run at this SCHED_FIFO priority (1-99), as the timer-driven hardware it stands for: the rover "
        "under test cannot make its sensors late (needs root or CAP_SYS_NICE; default 0: normal scheduling)",
    )
    peer.set_defaults(handler=run_peer_command)


def load_config(path: Path | None) -> RoverConfig:
    if path is None:
        return rover_config_from_table(parse_toml("", "<built-in defaults>"))
    return load_rover_config(path)


def _unique_run_dir(base: Path, name: str) -> Path:
    candidate = base / name
    counter = 2
    while candidate.exists():
        candidate = base / f"{name}-{counter}"
        counter += 1
    return candidate


def _usable_out_dir(path: Path) -> str | None:
    """Create the output folder now, so a bad ``--out`` is bad input (exit 2), not a traceback later."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        return f"--out {path}: exists and is not a directory"
    except OSError as err:
        return f"--out {path}: cannot create the folder: {err.strerror or err}"
    return None


def _earlier_run_problem(out_dir: Path, names: Sequence[str], what: str) -> str | None:
    """The files of ``names`` already in ``out_dir`` (an earlier run's, ``what``), named as bad input (exit
    2) before anything is written; None if there are none. Written over, they would be lost, or, left
    beside the new run's files, read as its own (an earlier report beside a new recording)."""
    earlier = [out_dir / name for name in names if (out_dir / name).exists()]
    if not earlier:
        return None
    one = len(earlier) == 1
    return (
        f"--out {out_dir}: {', '.join(map(str, earlier))} already {'exists' if one else 'exist'} ({what}; "
        f"{'it is' if one else 'they are'} left as {'it is' if one else 'they are'}): give --out a new "
        f"folder, or move {'that file' if one else 'those files'} away"
    )


def _peer_paths_problem(out_dir: Path, port_file: Path | None, status_file: Path | None) -> str | None:
    """What keeps the peer from writing its files, found before it runs (exit 2), else None.

    An earlier run's ``truth.mcap`` in ``--out`` is refused, as ``rover run`` refuses its ``rover.mcap``: the
    recorder would empty it, and that run's rover recording is reported against it.
    """
    from hil.peer import TRUTH_MCAP

    problem = _usable_out_dir(out_dir) or _earlier_run_problem(
        out_dir, (TRUTH_MCAP,), "an earlier run's ground truth"
    )
    if problem is not None:
        return problem
    for option, path in (("--port-file", port_file), ("--status-file", status_file)):
        if path is None:
            continue
        if path.is_dir():
            return f"{option} {path}: is a directory; give a file's path"
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            return f"{option} {path}: cannot create its folder: {err.strerror or err}"
    return None


def run_trial_command(args: argparse.Namespace) -> int:
    """Exit 0: the scenario's success criteria held; 1: they failed (each reason printed); 2: bad input."""
    from firmware_bridge.errors import BridgeSetupError
    from hil.scenario import load_scenario
    from hil.start_clearance import check_start_clear
    from hil.trial import run_trial
    from logs.errors import TelemetrySetupError
    from logs.telemetry import ZenohTelemetry, open_session
    from logs.telemetry_station import rate_limited

    console = Console()
    try:
        scenario = load_scenario(args.scenario)
        config = load_config(args.config)
        check_start_clear(scenario, config.vehicle)
    except ConfigError as err:
        print_error(console, err)
        return 2
    seed = scenario.seed if args.seed is None else args.seed
    out_dir = args.out or _unique_run_dir(DEFAULT_TRIALS_DIR, f"{scenario.name}-seed{seed}")
    problem = _usable_out_dir(out_dir) or _earlier_run_problem(
        out_dir, TRIAL_FILES, "an earlier trial's recording, metrics or report"
    )
    if problem is not None:
        print_error(console, problem)
        return 2

    session = None
    telemetry = None
    live: MessageSink | None = None
    started = time.perf_counter()
    try:
        if config.zenoh.enabled and not args.no_telemetry:
            session = open_session(config.zenoh)
            telemetry = ZenohTelemetry(session, config.rover_id)
            live = rate_limited(telemetry, config.zenoh.rates_hz)
        with console.status(f"running {scenario.name} (seed {seed}) ..."):
            result = run_trial(scenario, config, out_dir, seed=seed, telemetry=live)
    except TelemetrySetupError as err:
        print_error(console, err, f"{config.source}: telemetry")
        return 2
    except BridgeSetupError as err:  # e.g. the [vesc] dbc file changed since the config was loaded
        print_error(console, err, config.source)
        return 2
    finally:
        if telemetry is not None:
            telemetry.close()
        if session is not None:
            session.close()
    wall_s = time.perf_counter() - started

    console.print(_trial_table(f"{scenario.name}, seed {seed}: {result.end_reason}", result))
    if result.arrived_s is not None and result.parked_until_s is not None:
        console.print(
            f"ARRIVED at {result.arrived_s:.1f} s; parked until {result.parked_until_s:.1f} s for the "
            "scenario's faults still to run (docs/hil.md)"
        )
    console.print(_wall_time_line(wall_s, result.loop_wall_s, process_age_s()))
    console.print(f"recording: {result.mcap_path}\nmetrics:   {result.metrics_path}")
    verdict = _print_verdict(console, result.success, result.failures)
    if args.report:
        report_code = _write_trial_report(console, result.mcap_path, out_dir)
        if report_code != 0:
            return report_code
    return verdict


def _wall_time_line(trial_s: float, loop_s: float, process_s: float | None) -> str:
    """What the trial cost in wall time: since the process started where the kernel says (what `time`
    shows), else since the trial began."""
    if process_s is None:
        return (
            f"wall time: {trial_s:.2f} s for the trial (the loop {loop_s:.2f} s; the rest: loading or "
            "compiling the kernels, the metrics pass; Python's start-up and imports before it not counted)"
        )
    return (
        f"wall time: {process_s:.2f} s in all since the process started (the loop {loop_s:.2f} s; the "
        f"trial {trial_s:.2f} s with loading or compiling the kernels and the metrics pass; the rest: "
        "Python's start-up and imports, reading the scenario and config)"
    )


def _trial_table(title: str, result: TrialResult) -> RichTable:
    metrics = result.metrics
    table = RichTable(title=title)
    table.add_column("metric")
    table.add_column("value", justify="right")
    rows = [
        ("path accuracy (% of driven)", _fmt(metrics.path_accuracy_pct, "{:.1f}")),
        ("path accuracy (% of route)", _fmt(metrics.route_accuracy_pct, "{:.1f}")),
        ("obstacle-avoidance success (%)", _fmt(metrics.obstacle_avoidance_success_pct, "{:.1f}")),
        ("closest approach to an obstacle (m)", _fmt(metrics.closest_obstacle_m, "{:.2f}")),
        ("rollovers", _fmt(metrics.rollovers, "{}")),
        ("collisions", _fmt(metrics.collisions, "{}")),
        ("energy (Wh, net)", _fmt(metrics.energy_wh, "{:.3f}")),
        ("energy regenerated (Wh)", _fmt(metrics.energy_regenerated_wh, "{:.3f}")),
        ("distance (m)", _fmt(metrics.distance_m, "{:.2f}")),
        ("duration (s)", _fmt(metrics.duration_s, "{:.2f}")),
        ("goal reached (rover's ARRIVED)", _fmt(metrics.goal_reached, "{}")),
        ("distance to goal at end (m, truth)", _fmt(metrics.final_distance_to_goal_m, "{:.2f}")),
        # The loop alone: on a machine's first run the kernels compile first, for seconds, and that is not
        # the simulator's speed (the whole command's time is printed below the table).
        ("real-time factor", f"{result.simulated_s / max(result.loop_wall_s, 1e-9):.1f}x"),
    ]
    for name, value in rows:
        table.add_row(name, value)
    return table


def _print_verdict(console: Console, success: bool, failures: tuple[str, ...]) -> int:
    """The scenario's success verdict and every failed criterion; the exit code a gate reads."""
    if success:
        console.print("success criteria: [green]PASSED[/green]")
        return 0
    console.print("success criteria: [red]FAILED[/red]")
    for failure in failures:
        console.print(f"  - {failure}", markup=False, soft_wrap=True)
    return 1


def _write_trial_report(console: Console, mcap_path: Path, out_dir: Path) -> int:
    """``rover logs report`` of the trial just run, into its own folder (after the timed trial)."""
    from logs.errors import LogsError
    from logs.report import write_report

    try:
        report = write_report([mcap_path], out_dir)
    except LogsError as err:
        print_error(console, err, "report")
        return 2
    console.print(f"report:    {report.html}\n           {report.markdown}\n           {report.json}")
    return 0


def _fmt(value: object, pattern: str) -> str:
    return "n/a" if value is None else pattern.format(value)


def run_campaign_command(args: argparse.Namespace) -> int:
    from hil.campaign import load_campaign
    from hil.campaign_runner import run_campaign
    from rover_cli.progress import job_progress

    console = Console()
    try:
        campaign = load_campaign(args.campaign)
    except ConfigError as err:
        print_error(console, err)
        return 2
    out_dir = args.out or _unique_run_dir(DEFAULT_TRIALS_DIR, f"campaign-{campaign.name}")
    problem = _usable_out_dir(out_dir)
    if problem is not None:
        print_error(console, problem)
        return 2
    total = len(campaign.terrains) * len(campaign.variants) * len(campaign.seeds)
    with job_progress(console) as progress:
        task = progress.add_task(f"campaign {campaign.name}", total=total)

        def on_done(outcome: TrialOutcome) -> None:
            if not outcome.ok:
                status = f"[red]error[/red] {outcome.error}"
            else:
                status = f"{outcome.end_reason}, " + ("passed" if outcome.success else "[red]FAILED[/red]")
            progress.console.print(f"{outcome.spec.label}: {status} ({outcome.wall_s:.1f} s)")
            progress.advance(task)

        outcomes, markdown, json_path = run_campaign(campaign, out_dir, workers=args.workers, on_done=on_done)
    console.print(markdown.read_text(encoding="utf-8"), soft_wrap=True, markup=False)
    console.print(f"summary: {markdown}\n         {json_path}")
    return _print_campaign_verdict(console, outcomes)


def _print_campaign_verdict(console: Console, outcomes: list[TrialOutcome]) -> int:
    """Exit 0 only if every trial ran and met its scenario's success criteria; else 1, each failure listed."""
    failed = [o for o in outcomes if not (o.ok and o.success)]
    if not failed:
        console.print(f"success criteria: [green]PASSED[/green] in all {len(outcomes)} trials")
        return 0
    console.print(f"success criteria: [red]FAILED[/red] in {len(failed)} of {len(outcomes)} trials")
    for outcome in failed:
        reasons = [f"error: {outcome.error}"] if not outcome.ok else list(outcome.failures)
        line = f"  {outcome.spec.label} ({outcome.end_reason}): {'; '.join(reasons)}"
        console.print(line, markup=False, soft_wrap=True)
    return 1


def run_peer_command(args: argparse.Namespace) -> int:
    """Exit 0 when stopped (signal or ``--duration``); 1: ``--start-on-command`` and the rover never
    commanded within ``--start-timeout``; 2: bad input."""
    import dataclasses
    import signal
    import threading
    from types import FrameType

    from firmware_bridge.errors import BridgeError
    from hil.hardware_priority import raise_to_fifo
    from hil.peer import open_peer_wires, run_peer
    from hil.scenario import load_scenario
    from hil.start_clearance import check_start_clear
    from logs.clock import MonotonicClock

    console = Console(stderr=True)
    if args.start_timeout is not None and not args.start_on_command:
        print_error(console, "--start-timeout is how long --start-on-command waits: give both, or neither")
        return 2
    try:
        scenario = load_scenario(args.scenario)
        config = load_config(args.config)
        check_start_clear(scenario, config.vehicle)
        can_config = dataclasses.replace(
            config.can,
            interface=args.can_interface or config.can.interface,
            channel=args.can_channel or config.can.channel,
        )
        config = dataclasses.replace(config, can=can_config)
        bus, transport = open_peer_wires(can_config, args.mavlink)
    except (ConfigError, BridgeError) as err:
        print_error(console, err)
        return 2
    seed = scenario.seed if args.seed is None else args.seed
    out_dir = args.out or _unique_run_dir(DEFAULT_TRIALS_DIR, f"{scenario.name}-seed{seed}-peer")
    problem = _peer_paths_problem(out_dir, args.port_file, args.status_file)
    if problem is not None:
        transport.close()
        bus.shutdown()
        print_error(console, problem)
        return 2
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        del frame
        console.print(f"{signal.Signals(signum).name}: stopping the peer")
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    # The address the autopilot listens on, as bound (a loopback address --mavlink named, the OS's port).
    host, port = transport.local_address
    if args.fifo:
        console.print(f"scheduling: {raise_to_fifo(os.getpid(), args.fifo)}")

    def on_ready(rover_config: Path) -> None:
        # stdout is for whoever started us: the port to dial, then the config that dials it.
        print(f"mavlink: udpout:{host}:{port}", flush=True)
        print(f"rover config: {rover_config}", flush=True)

    try:
        result = run_peer(
            scenario,
            config,
            out_dir,
            clock=MonotonicClock(),
            can_bus=bus,
            mavlink=transport,
            mavlink_port=port,
            mavlink_host=host,
            wait=time.sleep,
            stop=stop,
            seed=seed,
            duration_ns=None if args.duration is None else round(args.duration * 1e9),
            status_path=args.status_file,
            port_file=args.port_file,
            on_ready=on_ready,
            start_on_command=args.start_on_command,
            start_timeout_ns=round((args.start_timeout or DEFAULT_START_TIMEOUT_S) * 1e9),
        )
    finally:
        transport.close()
        bus.shutdown()
    print(f"truth: {result.mcap_path}")
    print(
        f"simulated {result.simulated_s:.1f} s; VESC commands {result.commands_applied}, "
        f"command timeouts {result.vesc_timeouts}; steps: {result.timing.describe()}; "
        f"{result.stalls.describe()}; {result.describe_bus_off()}"
    )
    print(result.start.describe())
    return 1 if result.start.timed_out else 0
