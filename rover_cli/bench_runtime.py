"""``rover bench runtime``: real-time HIL at the control rate; loop jitter, sensor-to-command latency, CPU.

The onboard stack runs in this thread after the same start-up warm-up as ``rover run``, with planning on a
worker thread, recording to MCAP and (unless ``--no-telemetry``) publishing on Zenoh with the shipped
loopback config, in one or both of two loops (``--modes``), one after the other against the same kind of
simulated rover:

* ``paced``: the sensor-synchronous loop ``rover run`` uses (``navigator.rover_process.paced_scheduler``:
  a tick on each IMU sample, busy-polling the MAVLink socket around the expected sample for
  ``busy_poll_ms`` of the config, a fixed-rate deadline as the fallback);
* ``fixed``: ``navigator.runtime.FixedRateScheduler`` at the control rate, with the precise wait (sleep,
  then spin the last millisecond), reading the links between ticks (``navigator.fixed_rate_stack``).

The simulated rover (``hil.bench_rover``) runs at 100 Hz: six VESCs on CAN and the autopilot over MAVLink
on UDP 127.0.0.1 (a port from the OS), each step on a precise timer as a real IMU is (``--peer-spin-ms``,
0: a plain sleep). Where it can, it is a separate process, as the real rover's autopilot and motor
controllers are separate hardware: CAN is python-can ``udp_multicast``, which runs only inside the private
loopback-only network namespace (``scripts/in-private-netns`` sets ``ROVER_IN_NETNS=1``). That process
runs at ``SCHED_FIFO`` (``--peer-fifo``, ``hil.hardware_priority``) where the bench may set it, so the
stack's own threads cannot make the sensor it is timed against late; the table says what was applied.
Elsewhere it is a thread in this process on a ``virtual`` bus, and then shares the GIL with the control
loop: its IMU timing, which paces the loop, takes the stack's compute time as jitter. The table says
which mode ran.

Peers measured in the same run: the fixed-rate scheduler with an empty tick, waiting with a plain sleep
and with the precise wait (what the OS and Python give at best), and the full stack in each loop. CPU is
the control thread's own (RUSAGE_THREAD). ``--trace`` adds, for the paced loop, where each tick's jitter
and latency came from (``hil.jitter_trace``).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import multiprocessing
import os
import resource
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from hil.hardware_priority import PEER_FIFO_PRIORITY
from logs.clock import MonotonicClock
from navigator.precise_wait import DEFAULT_SPIN_NS
from rover_cli.arg_types import bounded_float, fifo_priority

RATE_HZ = 50.0
MODES = ("paced", "fixed", "locked")
# `rover run` runs at this nice value under deploy/rover.service (Nice=); the bench measures it so.
DEPLOYED_NICE = -10
# The modes that run `rover run`'s own loop (`control_loop`); "fixed" is the free-running comparison.
LOOPS = {"paced": "sensor-paced", "locked": "phase-locked"}
EMPTY_TICK_S = 10.0  # each empty-tick peer runs this long at most


def register(commands: Any) -> None:
    bench = commands.add_parser("runtime", help="real-time loop jitter and sensor-to-command latency")
    bench.add_argument("--seconds", type=float, default=60.0, help="length of each full-stack run")
    bench.add_argument("--no-telemetry", action="store_true", help="record only (no Zenoh)")
    bench.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    bench.add_argument(
        "--modes",
        type=_modes,
        default=MODES,
        help="loops to run, comma-separated: paced, fixed, locked (default all three)",
    )
    bench.add_argument(
        "--peer-spin-ms",
        type=float,
        default=DEFAULT_SPIN_NS / 1e6,
        help="the simulated rover spins this long before each step (0: plain sleep)",
    )
    bench.add_argument(
        "--peer-fifo",
        type=fifo_priority,
        default=PEER_FIFO_PRIORITY,
        help=f"run the simulated rover's process at this SCHED_FIFO priority, as timer-driven hardware "
        f"(default {PEER_FIFO_PRIORITY}; 0: normal scheduling, as the stack)",
    )
    # Both checked as the config checks them, when the command line is read: an offset the scheduler
    # refuses was a ValueError traceback once the locked run began (after the other runs), and one past
    # half a period (which the scheduler takes) measured a loop no config can ask for.
    bench.add_argument(
        "--busy-poll-ms",
        type=bounded_float(0.0, 10.0, "as busy_poll_ms in the config"),
        default=None,
        help="override the config's busy_poll_ms (paced loop)",
    )
    bench.add_argument(
        "--phase-offset-ms",
        type=bounded_float(0.0, 500.0 / RATE_HZ, f"at most half the {RATE_HZ:g} Hz period, as the config"),
        default=None,
        help="override the config's phase_offset_ms (phase-locked loop)",
    )
    bench.add_argument(
        "--phase-late-wait-ms",
        type=bounded_float(0.0, 500.0 / RATE_HZ, f"at most half the {RATE_HZ:g} Hz period, as the config"),
        default=None,
        help="override the config's phase_late_wait_ms (phase-locked loop)",
    )
    bench.add_argument(
        "--nice",
        type=nice_value,
        default=DEPLOYED_NICE,
        help=f"run at this nice value, the simulated rover too (default {DEPLOYED_NICE}, as "
        "deploy/rover.service; 'keep': leave it)",
    )
    bench.add_argument("--trace", action="store_true", help="split the paced loop's jitter and latency")
    bench.set_defaults(handler=run_bench)


def nice_value(text: str) -> int | None:
    if text == "keep":
        return None
    try:
        value = int(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(
            f"expected an integer from -20 to 19 or 'keep', got {text!r}"
        ) from err
    if not -20 <= value <= 19:
        raise argparse.ArgumentTypeError(f"expected an integer from -20 to 19 or 'keep', got {text!r}")
    return value


def _modes(text: str) -> tuple[str, ...]:
    modes = tuple(m.strip() for m in text.split(",") if m.strip())
    unknown = [m for m in modes if m not in MODES]
    if not modes or unknown:
        raise argparse.ArgumentTypeError(f"modes are {', '.join(MODES)}; got {text!r}")
    return modes


def _thread_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_THREAD)
    return usage.ru_utime + usage.ru_stime


def _empty_loop(duration_s: float, spin_ns: int) -> dict[str, Any]:
    from navigator.runtime import FixedRateScheduler

    cpu0, wall0 = _thread_cpu_s(), time.perf_counter()
    scheduler = FixedRateScheduler(MonotonicClock(), RATE_HZ, lambda: None, wait=time.sleep, spin_ns=spin_ns)
    figures = scheduler.run(round(duration_s * 1e9)).summary()
    figures["cpu_pct"] = 100.0 * (_thread_cpu_s() - cpu0) / (time.perf_counter() - wall0)
    return figures


@dataclasses.dataclass(frozen=True)
class StackRun:
    """One full-stack run's settings."""

    seconds: float
    telemetry: bool
    mode: str  # one of MODES
    peer_spin_ns: int
    peer_fifo: int  # SCHED_FIFO priority of the simulated rover's process; 0: normal scheduling
    busy_poll_ms: float | None  # None: the config's
    phase_offset_ms: float | None  # None: the config's
    phase_late_wait_ms: float | None  # None: the config's
    trace: bool


def _full_stack(run: StackRun) -> dict[str, Any]:
    from firmware_bridge.can_link import CanLink, open_bus
    from firmware_bridge.mavlink_link import MavlinkLink
    from firmware_bridge.mavlink_transport import UdpTransport
    from firmware_bridge.vesc import VescCodec
    from hil.bench_rover import DATUM, run_sim_rover
    from hil.hardware_priority import raise_to_fifo
    from hil.jitter_trace import RoverTrace, breakdown
    from logs.recorder import McapRecorder
    from logs.settings import parse_toml
    from logs.sink import FanoutSink, MessageSink
    from logs.telemetry import ZenohTelemetry, open_session
    from navigator.config import rover_config_from_table
    from navigator.deferred_sink import deferred_sink
    from navigator.fixed_rate_stack import FixedRateFeed
    from navigator.input_wait import input_poller, input_waiter
    from navigator.onboard import OnboardStack
    from navigator.plan_worker import plan_worker
    from navigator.rover_process import control_scheduler
    from navigator.runtime import (
        FixedRateScheduler,
        TimingStats,
        freeze_start_up_heap,
        realtime_switch_interval,
    )
    from navigator.terrain import from_maze
    from navigator.warm_up import warm_up

    config = rover_config_from_table(parse_toml(Path("configs/rover.toml").read_text(), "configs/rover.toml"))
    estimator = dataclasses.replace(
        config.estimator, datum_lat_deg=DATUM[0], datum_lon_deg=DATUM[1], datum_alt_m=DATUM[2]
    )
    config = dataclasses.replace(config, estimator=estimator, control_rate_hz=RATE_HZ)
    if run.busy_poll_ms is not None:
        config = dataclasses.replace(config, busy_poll_ms=run.busy_poll_ms)
    if run.phase_offset_ms is not None:
        config = dataclasses.replace(config, phase_offset_ms=run.phase_offset_ms)
    if run.phase_late_wait_ms is not None:
        config = dataclasses.replace(config, phase_late_wait_ms=run.phase_late_wait_ms)
    if _peer_as_process():
        # A group of its own per bench run, so a leftover peer can never talk to this rover.
        salt = os.getpid() + MODES.index(run.mode) * 97
        group = f"239.76.{(salt >> 8) % 200 + 10}.{salt % 250 + 1}"
        bus_config = dataclasses.replace(config.can, interface="udp_multicast", channel=group)
    else:
        bus_config = dataclasses.replace(
            config.can, interface="virtual", channel=f"bench-runtime-{time.monotonic_ns()}"
        )
    terrain = from_maze(np.full((20, 20), 2), 2.0)
    clock = MonotonicClock()
    trace = RoverTrace() if run.trace and run.mode == "paced" else None
    # Every resource is closed in reverse order however the run ends (a peer that never starts included).
    with contextlib.ExitStack() as cleanup:
        session = open_session(config.zenoh) if run.telemetry else None
        if session is not None:
            cleanup.callback(session.close)
        tmp = Path(cleanup.enter_context(tempfile.TemporaryDirectory()))
        recorder = cleanup.enter_context(McapRecorder(tmp / "bench.mcap"))
        publisher = ZenohTelemetry(session, config.rover_id) if session is not None else None
        if publisher is not None:
            cleanup.callback(publisher.close)
        sink: MessageSink = recorder if publisher is None else FanoutSink([recorder, publisher])
        deferred = deferred_sink(sink)
        mavlink_transport = UdpTransport("udpin", "127.0.0.1", 0)
        codec = VescCodec.for_profile(config.vesc)
        can_link = CanLink(open_bus(bus_config), codec, clock, deferred)
        mavlink = MavlinkLink(mavlink_transport, clock, deferred)
        planning = plan_worker()
        cleanup.callback(planning.shutdown, wait=False, cancel_futures=True)
        stack = OnboardStack(
            config, clock, can_link, mavlink, deferred, terrain, deferred=deferred, planning=planning
        )
        cleanup.callback(stack.close)
        warm_up(stack.planner, config, clock)
        stack.publish_map()
        stack.set_goal(35.0, 35.0)
        trace_path = tmp / "imu_sends.npy" if trace is not None else None
        peer_args = (
            bus_config,
            mavlink_transport.local_address[1],
            config,
            terrain,
            run.peer_spin_ns,
            trace_path,
        )
        peer: threading.Thread | multiprocessing.process.BaseProcess
        peer_stop: Any
        if _peer_as_process():
            context = multiprocessing.get_context("spawn")  # a fresh interpreter: no inherited threads
            peer_stop = context.Event()
            peer = context.Process(target=run_sim_rover, args=(peer_stop, *peer_args), daemon=True)
        else:
            peer_stop = threading.Event()
            peer = threading.Thread(target=run_sim_rover, args=(peer_stop, *peer_args), daemon=True)
        peer.start()
        cleanup.callback(peer.join, 5.0)
        if isinstance(peer, threading.Thread):
            # It shares the GIL with the loop under test: a priority would not make its sends punctual.
            peer_scheduling = "normal scheduling (a thread of this process)"
        else:
            assert peer.pid is not None  # started
            peer_scheduling = raise_to_fifo(peer.pid, run.peer_fifo)
        cleanup.callback(peer_stop.set)
        _wait_for_first_sample(mavlink_transport, PEER_START_TIMEOUT_S)
        wait = input_waiter([mavlink_transport])
        poll = input_poller([mavlink_transport])
        if trace is not None:
            wait = trace.wrap_wait(wait)
            poll = trace.wrap_poll(poll) if poll is not None else None
        scheduler: Any
        if run.mode in LOOPS:
            scheduler = control_scheduler(
                stack,
                clock,
                dataclasses.replace(config, control_loop=LOOPS[run.mode]),
                deferred,
                wait,
                poll=poll,
                observe=trace.observe if trace is not None else None,
            )
        else:
            feed = FixedRateFeed(stack)
            scheduler = FixedRateScheduler(
                clock,
                RATE_HZ,
                feed.tick,
                ingest=feed.ingest,
                wait=wait,
                latency=lambda: stack.last_sensor_to_command_ns,
                spin_ns=DEFAULT_SPIN_NS,
            )
        freeze_start_up_heap()  # as `rover run` does
        cpu0, wall0 = _thread_cpu_s(), time.perf_counter()
        stats: TimingStats
        try:
            with realtime_switch_interval():
                stats = scheduler.run(round(run.seconds * 1e9))
        finally:
            cpu = 100.0 * (_thread_cpu_s() - cpu0) / (time.perf_counter() - wall0)
        peer_stop.set()
        peer.join(5.0)
        imu_sends = np.load(trace_path) if trace_path is not None and trace_path.exists() else None
    figures = stats.summary()
    figures["cpu_pct"] = cpu
    figures["final_mode"] = stack.safety_mode.value
    figures["simulated_rover"] = "process" if _peer_as_process() else "thread"
    figures["simulated_rover_scheduling"] = peer_scheduling
    figures["busy_poll_ms"] = config.busy_poll_ms if run.mode == "paced" else None
    if run.mode == "paced":
        figures["busy_polls"] = scheduler.busy_polls
    figures["phase_offset_ms"] = config.phase_offset_ms if run.mode == "locked" else None
    figures["phase_late_wait_ms"] = config.phase_late_wait_ms if run.mode == "locked" else None
    if run.mode == "locked":
        figures["locks"] = scheduler.locks
        # Ticks whose sample was not in by the end of the late wait: each is two periods of jitter of
        # about the late wait, and a sample answered a period later (its latency), so they set both p99s.
        figures["late_waits_missed"] = scheduler.late_waits_missed
    if trace is not None:
        figures["trace"] = (
            breakdown(imu_sends, trace, round(1e9 / RATE_HZ))
            if imu_sends is not None
            else {"error": "the simulated rover wrote no trace"}
        )
    return figures


PEER_START_TIMEOUT_S = 30.0  # a spawned peer imports and loads its compiled kernels first


def _peer_as_process() -> bool:
    return os.environ.get("ROVER_IN_NETNS") == "1"


def _wait_for_first_sample(transport: Any, timeout_s: float) -> None:
    """Block until the simulated autopilot's first datagram is waiting, so the timed run starts with the
    peer up (a spawned peer takes a second or two to start)."""
    import select

    ready, _, _ = select.select([transport.fileno()], [], [], timeout_s)
    if not ready:
        raise RuntimeError(f"the simulated rover sent nothing within {timeout_s:g} s")


def apply_nice(nice: int | None) -> str:
    """Run this process (and the simulated rover it starts, which inherits it) at ``nice``, as
    ``deploy/rover.service`` runs ``rover run``; says what was done (lowering it needs privilege)."""
    if nice is None:
        return f"nice {os.getpriority(os.PRIO_PROCESS, 0)} (left as it was)"
    try:
        os.setpriority(os.PRIO_PROCESS, 0, nice)
    except (PermissionError, OSError) as err:
        return f"nice {os.getpriority(os.PRIO_PROCESS, 0)} (could not set {nice}: {err.strerror or err})"
    return f"nice {nice}, as deploy/rover.service runs rover run"


def run_bench(args: argparse.Namespace) -> int:
    priority = apply_nice(args.nice)
    empty_s = min(EMPTY_TICK_S, args.seconds)
    peers = {
        "empty tick, sleep": _empty_loop(empty_s, 0),
        "empty tick, precise wait": _empty_loop(empty_s, DEFAULT_SPIN_NS),
    }
    extras = "recording" + ("" if args.no_telemetry else " + telemetry")
    for mode in args.modes:
        loop = LOOPS.get(mode, "fixed-rate")
        peers[f"stack, {loop} + {extras}"] = _full_stack(
            StackRun(
                seconds=args.seconds,
                telemetry=not args.no_telemetry,
                mode=mode,
                peer_spin_ns=round(args.peer_spin_ms * 1e6),
                peer_fifo=args.peer_fifo,
                busy_poll_ms=args.busy_poll_ms,
                phase_offset_ms=args.phase_offset_ms,
                phase_late_wait_ms=args.phase_late_wait_ms,
                trace=args.trace,
            )
        )
    if args.json:
        # NaN (no latency samples for the empty tick) is not JSON: write null.
        print(json.dumps(_no_nan({"rate_hz": RATE_HZ, "priority": priority, "peers": peers}), indent=2))
        return 0
    _print_tables(args, peers, priority)
    return 0


def _print_tables(args: argparse.Namespace, peers: dict[str, dict[str, Any]], priority: str) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(
        title=f"rover bench runtime: {RATE_HZ:g} Hz real-time HIL, {args.seconds:g} s per loop "
        "(goals: p99 jitter <= 1 ms, p99 latency <= 2 ms)"
    )
    columns = ("peer", "ticks (sensor/deadline)", "overruns", "jitter p50/p99/max ms", "latency p50/p99/max")
    stacks = [f for name, f in peers.items() if name.startswith("stack")]
    busy = next((f["busy_poll_ms"] for f in stacks if f.get("busy_poll_ms") is not None), None)
    locked = next((f for f in stacks if f.get("phase_offset_ms") is not None), None)
    table.caption = (
        f"simulated rover ran as a {stacks[0]['simulated_rover']} at "
        f"{stacks[0]['simulated_rover_scheduling']}, stepping on a "
        + (f"{args.peer_spin_ms:g} ms spin" if args.peer_spin_ms > 0 else "plain sleep")
        + ("" if busy is None else f"; paced loop busy-polls {busy:g} ms")
        + (
            ""
            if locked is None
            else f"; phase-locked loop ticks {locked['phase_offset_ms']:g} ms after the expected IMU sample, "
            f"waiting {locked['phase_late_wait_ms']:g} ms more for a late one "
            f"({locked['late_waits_missed']} of {locked['ticks']} ticks waited in vain)"
        )
        + f"; the stack at {priority}"
    )
    for column in (*columns, "CPU %"):
        table.add_column(column)
    for name, f in peers.items():
        table.add_row(
            name,
            f"{f['ticks']} ({f['sensor_ticks']}/{f['deadline_ticks']})",
            str(f["overruns"]),
            _triple(f["jitter"]),
            _triple(f["latency"]),
            f"{f['cpu_pct']:.1f}",
        )
    console = Console()
    console.print(table)
    for f in stacks:
        if "trace" in f and "parts" in f["trace"]:
            console.print(_trace_table(f["trace"]))


def _trace_table(trace: dict[str, Any]) -> Any:
    from rich.table import Table

    table = Table(
        title=f"sensor-paced loop, where it went ({trace['matched_ticks']} ticks matched to IMU sends): "
        "as it is, and its change tick to tick (adds to period jitter), p50/p99/max ms"
    )
    for column in ("part", "as it is", "tick-to-tick change"):
        table.add_column(column)
    table.add_row("IMU send period jitter", "", _triple(trace["imu_period_jitter"]))
    for name, summary in trace["parts"].items():
        change = trace["parts_jitter"].get(name)
        table.add_row(name, _triple(summary), "" if change is None else _triple(change))
    table.add_row("tick period jitter (matched)", "", _triple(trace["tick_period_jitter"]))
    busy = 100 * trace["wait_returned_before_send"]
    table.caption = f"the rover's wait returned before the IMU send on {busy:.0f} % of ticks (it was busy)"
    return table


def _triple(summary: Any) -> str:
    if summary["p50_ms"] is None:  # no samples
        return "none"
    return f"{summary['p50_ms']:.3f} / {summary['p99_ms']:.3f} / {summary['max_ms']:.3f}"


def _no_nan(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _no_nan(v) for k, v in value.items()}
    if isinstance(value, float) and value != value:
        return None
    return value
