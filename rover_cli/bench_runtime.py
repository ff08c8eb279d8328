"""``rover bench runtime``: real-time HIL at the control rate; loop jitter, sensor-to-command latency, CPU.

The onboard stack runs in this thread in the sensor-synchronous loop ``rover run`` uses
(``navigator.rover_process.paced_scheduler``: a tick on each IMU sample, a fixed-rate deadline as the
fallback), with planning on a worker thread, after the same start-up warm-up; it records to MCAP and
(unless ``--no-telemetry``) publishes on Zenoh with the shipped loopback config. The simulated rover runs
at 100 Hz: six VESCs on CAN and the autopilot over MAVLink on UDP 127.0.0.1 (a port from the OS).

Where it can, the simulated rover is a separate process, as the real rover's autopilot and motor
controllers are separate hardware: CAN is python-can ``udp_multicast``, which runs only inside the private
loopback-only network namespace (``scripts/in-private-netns`` sets ``ROVER_IN_NETNS=1``). Elsewhere it is
a thread in this process on a ``virtual`` bus, and then shares the GIL with the control loop: its IMU
timing, which paces the loop, takes the stack's compute time as jitter (measured: p99 2.3 ms in a thread,
against well under 1 ms as a process). The table says which mode ran.

Peers measured in the same run: the scheduler with an empty tick (what the OS and Python give at best)
and the full stack. CPU is the control thread's own (RUSAGE_THREAD).
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

from logs.clock import MonotonicClock, seconds

DATUM = (47.0, 8.0, 400.0)
SIM_DT_NS = 10_000_000


def register(commands: Any) -> None:
    bench = commands.add_parser("runtime", help="real-time loop jitter and sensor-to-command latency")
    bench.add_argument("--seconds", type=float, default=60.0, help="length of the full-stack run")
    bench.add_argument("--no-telemetry", action="store_true", help="record only (no Zenoh)")
    bench.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    bench.set_defaults(handler=run_bench)


def _thread_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_THREAD)
    return usage.ru_utime + usage.ru_stime


def _empty_loop(duration_s: float) -> dict[str, Any]:
    from navigator.runtime import FixedRateScheduler

    cpu0, wall0 = _thread_cpu_s(), time.perf_counter()
    stats = FixedRateScheduler(MonotonicClock(), 50.0, lambda: None, wait=time.sleep).run(
        round(duration_s * 1e9)
    )
    figures = stats.summary()
    figures["cpu_pct"] = 100.0 * (_thread_cpu_s() - cpu0) / (time.perf_counter() - wall0)
    return figures


def _sim_peer(stop: Any, bus_config: Any, mavlink_port: int, config: Any, terrain: Any) -> None:
    """The simulated rover, paced on the monotonic clock at 100 Hz until ``stop`` (a threading or a
    multiprocessing event) is set. Runs in a thread or as a process's target: it opens its own bus."""
    from firmware_bridge.can_link import open_bus
    from firmware_bridge.mavlink_transport import UdpTransport
    from firmware_bridge.vesc import VescCodec
    from firmware_bridge.vesc_dbc import load_vesc_database
    from hil.autopilot_sim import AutopilotTruth, SimAutopilot
    from hil.dynamics import RoverDynamics
    from hil.vesc_sim import SimVescBank

    clock = MonotonicClock()
    bus = open_bus(bus_config)
    codec = VescCodec(load_vesc_database(config.vesc.controller_ids), config.vesc)
    vescs = SimVescBank(bus, codec, clock)
    transport = UdpTransport("udpout", "127.0.0.1", mavlink_port)
    autopilot = SimAutopilot(
        transport,
        clock,
        np.random.default_rng(1),
        datum_lat_deg=DATUM[0],
        datum_lon_deg=DATUM[1],
        datum_alt_m=DATUM[2],
    )
    body = RoverDynamics(terrain, config.vehicle, x=5.0, y=5.0, yaw=0.785)
    due = clock.now_ns()
    dt_s = seconds(SIM_DT_NS)
    truth: AutopilotTruth | None = None
    while not stop.is_set():
        # The autopilot sends first, on the wake-up, with the state the last step ended in: a real IMU
        # samples on its own timer. Sending after the physics step would stamp the step's varying compute
        # time onto the IMU's timing, and the sensor-synchronous loop would inherit it as jitter.
        if truth is not None:
            autopilot.step(truth)
        autopilot.poll()
        vescs.poll()
        step = body.step(dt_s, vescs.wheel_speeds_mps(), 24.0)
        vescs.set_electrical(step.motor_currents_a, 24.0)
        vescs.step(dt_s)
        truth = AutopilotTruth(
            x_m=body.x,
            y_m=body.y,
            z_m=0.0,
            yaw_rad=body.yaw,
            speed_mps=body.speed,
            yaw_rate_rps=body.yaw_rate,
            accel_body_mps2=step.specific_force_body_mps2,
        )
        due += SIM_DT_NS
        remaining = due - clock.now_ns()
        if remaining > 0:
            time.sleep(remaining / 1e9)
    transport.close()
    bus.shutdown()


def _full_stack(duration_s: float, telemetry: bool) -> dict[str, Any]:
    from firmware_bridge.can_link import CanLink, open_bus
    from firmware_bridge.mavlink_link import MavlinkLink
    from firmware_bridge.mavlink_transport import UdpTransport
    from firmware_bridge.vesc import VescCodec
    from firmware_bridge.vesc_dbc import load_vesc_database
    from logs.recorder import McapRecorder
    from logs.settings import parse_toml
    from logs.sink import FanoutSink, MessageSink
    from logs.telemetry import ZenohTelemetry, open_session
    from navigator.config import rover_config_from_table
    from navigator.deferred_sink import deferred_sink
    from navigator.input_wait import input_waiter
    from navigator.onboard import OnboardStack
    from navigator.plan_worker import plan_worker
    from navigator.rover_process import paced_scheduler, warm_up_planner
    from navigator.runtime import realtime_switch_interval
    from navigator.terrain import from_maze

    config = rover_config_from_table(parse_toml(Path("configs/rover.toml").read_text(), "configs/rover.toml"))
    estimator = dataclasses.replace(
        config.estimator, datum_lat_deg=DATUM[0], datum_lon_deg=DATUM[1], datum_alt_m=DATUM[2]
    )
    config = dataclasses.replace(config, estimator=estimator)
    if _peer_as_process():
        # A group of its own per bench process, so a leftover peer can never talk to this rover.
        group = f"239.76.{(os.getpid() >> 8) % 200 + 10}.{os.getpid() % 250 + 1}"
        bus_config = dataclasses.replace(config.can, interface="udp_multicast", channel=group)
    else:
        bus_config = dataclasses.replace(
            config.can, interface="virtual", channel=f"bench-runtime-{time.monotonic_ns()}"
        )
    terrain = from_maze(np.full((20, 20), 2), 2.0)
    clock = MonotonicClock()
    # Every resource is closed in reverse order however the run ends (a peer that never starts included).
    with contextlib.ExitStack() as cleanup:
        session = open_session(config.zenoh) if telemetry else None
        if session is not None:
            cleanup.callback(session.close)
        tmp = cleanup.enter_context(tempfile.TemporaryDirectory())
        recorder = cleanup.enter_context(McapRecorder(Path(tmp) / "bench.mcap"))
        publisher = ZenohTelemetry(session, config.rover_id) if session is not None else None
        if publisher is not None:
            cleanup.callback(publisher.close)
        sink: MessageSink = recorder if publisher is None else FanoutSink([recorder, publisher])
        deferred = deferred_sink(sink)
        mavlink_transport = UdpTransport("udpin", "127.0.0.1", 0)
        codec = VescCodec(load_vesc_database(config.vesc.controller_ids), config.vesc)
        can_link = CanLink(open_bus(bus_config), codec, clock, deferred)
        mavlink = MavlinkLink(mavlink_transport, clock, deferred)
        planning = plan_worker()
        cleanup.callback(planning.shutdown, wait=False, cancel_futures=True)
        stack = OnboardStack(
            config, clock, can_link, mavlink, deferred, terrain, deferred=deferred, planning=planning
        )
        cleanup.callback(stack.close)
        warm_up_planner(stack.planner, clock)
        stack.publish_map()
        stack.set_goal(35.0, 35.0)
        peer_args = (bus_config, mavlink_transport.local_address[1], config, terrain)
        peer: threading.Thread | multiprocessing.process.BaseProcess
        peer_stop: Any
        if _peer_as_process():
            context = multiprocessing.get_context("spawn")  # a fresh interpreter: no inherited threads
            peer_stop = context.Event()
            peer = context.Process(target=_sim_peer, args=(peer_stop, *peer_args), daemon=True)
        else:
            peer_stop = threading.Event()
            peer = threading.Thread(target=_sim_peer, args=(peer_stop, *peer_args), daemon=True)
        peer.start()
        cleanup.callback(peer.join, 5.0)
        cleanup.callback(peer_stop.set)
        _wait_for_first_sample(mavlink_transport, PEER_START_TIMEOUT_S)
        scheduler = paced_scheduler(stack, clock, config, deferred, input_waiter([mavlink_transport]))
        cpu0, wall0 = _thread_cpu_s(), time.perf_counter()
        try:
            with realtime_switch_interval():
                stats = scheduler.run(round(duration_s * 1e9))
        finally:
            cpu = 100.0 * (_thread_cpu_s() - cpu0) / (time.perf_counter() - wall0)
    figures = stats.summary()
    figures["cpu_pct"] = cpu
    figures["final_mode"] = stack.safety_mode.value
    figures["simulated_rover"] = "process" if _peer_as_process() else "thread"
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


def run_bench(args: argparse.Namespace) -> int:
    peers = {
        "empty tick (scheduler only)": _empty_loop(min(10.0, args.seconds)),
        "stack + recording" + ("" if args.no_telemetry else " + telemetry"): _full_stack(
            args.seconds, not args.no_telemetry
        ),
    }
    if args.json:
        # NaN (no latency samples for the empty tick) is not JSON: write null.
        print(json.dumps(_no_nan({"rate_hz": 50.0, "peers": peers}), indent=2))
        return 0
    from rich.console import Console
    from rich.table import Table

    table = Table(
        title=f"rover bench runtime: 50 Hz real-time HIL, {args.seconds:g} s "
        "(goals: p99 jitter <= 1 ms, p99 latency <= 2 ms)"
    )
    columns = ("peer", "ticks (sensor/deadline)", "overruns", "jitter p50/p99/max ms", "latency p50/p99/max")
    full = next(f for name, f in peers.items() if name.startswith("stack"))
    table.caption = f"simulated rover ran as a {full['simulated_rover']}"
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
    Console().print(table)
    return 0


def _triple(summary: Any) -> str:
    return f"{summary['p50_ms']:.3f} / {summary['p99_ms']:.3f} / {summary['max_ms']:.3f}"


def _no_nan(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _no_nan(v) for k, v in value.items()}
    if isinstance(value, float) and value != value:
        return None
    return value
