"""``rover bench hil``: the real-time factor of a full lockstep trial, per-component time, and its peers.

Measured in one run, on the same scenario and seed:

* ``lockstep``: the full trial as ``rover hil trial`` runs it (CAN, MAVLink, estimator, planner, follower,
  MCAP, Zenoh when enabled, metrics at the end). The headline figure.
* ``lockstep-virtual-can``: the same with python-can's own ``virtual`` bus between the rover and the
  simulated controllers instead of ``hil.lockstep_bus`` (the walking skeleton's wiring).
* ``world-only``: the simulated world and its peers without the onboard stack, recording to nowhere; the
  ceiling the simulator alone allows.

The per-component breakdown comes from a separate instrumented run: each component's entry points are
wrapped with a timer that subtracts the time spent in nested timed calls, so the shares are exclusive
and add up to the loop. Wall time via ``time.perf_counter`` (benchmarks may read it; components never do).
"""

from __future__ import annotations

import functools
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.lockstep import CanBackend, lockstep_wires
from hil.scenario import Scenario
from hil.trial import PHYSICS_DT_NS, run_trial
from logs.clock import SimClock, seconds, to_ns
from logs.metrics import compute_metrics
from logs.sink import MessageSink
from navigator.config import RoverConfig

# component name -> methods timed on it
TIMED_METHODS: dict[str, tuple[str, ...]] = {
    "onboard": ("step", "set_goal"),
    "can_link": ("poll", "send_wheel_speeds"),
    "mavlink_link": ("poll", "send_heartbeat"),
    "recorder": ("publish",),
    "telemetry": ("publish",),
    "world": ("tick",),
    "vescs": ("poll", "step"),
    "autopilot": ("step", "poll", "record_truth"),
    "dynamics": ("step",),
    "truth": ("on_step",),
}
# What each timed component stands for in the report.
COMPONENT_LABELS = {
    "onboard": "onboard stack (estimator, planner, follower, safety)",
    "can_link": "CAN link (onboard: encode, decode, python-can bus)",
    "mavlink_link": "MAVLink link (onboard: parse, record raw)",
    "recorder": "MCAP recording (JSON encoding + writer)",
    "telemetry": "Zenoh telemetry",
    "world": "sim world glue (faults, battery, moving obstacles)",
    "vescs": "simulated VESCs (status frames, python-can bus)",
    "autopilot": "simulated autopilot (sensors, MAVLink encode)",
    "dynamics": "rover dynamics (physics)",
    "truth": "ground truth (building messages)",
}


class _NullSink:
    def publish(self, topic: str, log_time_ns: int, message: dict[str, Any]) -> None:
        return None


@dataclass
class ExclusiveTimer:
    """Times wrapped calls; a call's own time excludes the timed calls nested inside it."""

    totals_s: dict[str, float] = field(default_factory=dict)
    calls: dict[str, int] = field(default_factory=dict)
    _stack: list[list[float]] = field(default_factory=list)  # per open call: [child seconds]

    def wrap(self, name: str, method: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(method)
        def timed(*args: Any, **kwargs: Any) -> Any:
            self._stack.append([0.0])
            started = time.perf_counter()
            try:
                return method(*args, **kwargs)
            finally:
                elapsed = time.perf_counter() - started
                children = self._stack.pop()[0]
                self.totals_s[name] = self.totals_s.get(name, 0.0) + elapsed - children
                self.calls[name] = self.calls.get(name, 0) + 1
                if self._stack:
                    self._stack[-1][0] += elapsed

        return timed

    def instrument(self, components: dict[str, Any]) -> None:
        for name, component in components.items():
            if component is None:
                continue
            for method_name in TIMED_METHODS.get(name, ()):
                method = getattr(component, method_name, None)
                if callable(method):
                    # An instance attribute shadows the class's method: only this object is timed.
                    setattr(component, method_name, self.wrap(name, method))


@dataclass(frozen=True)
class PeerFigure:
    name: str
    wall_s: float
    simulated_s: float

    @property
    def real_time_factor(self) -> float:
        return self.simulated_s / self.wall_s if self.wall_s > 0 else float("inf")


def pin_to_one_core() -> int | None:
    """Run on one CPU (the first this process may use), as the benchmark promises; None if not possible."""
    try:
        allowed = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {allowed[0]})
        return allowed[0]
    except (AttributeError, OSError):
        return None


def time_trial(
    scenario: Scenario,
    config: RoverConfig,
    work_dir: Path,
    name: str,
    *,
    telemetry: MessageSink | None,
    can_backend: CanBackend = "lockstep",
    timer: ExclusiveTimer | None = None,
) -> PeerFigure:
    out_dir = work_dir / name
    started = time.perf_counter()
    result = run_trial(
        scenario,
        config,
        out_dir,
        telemetry=telemetry,
        can_backend=can_backend,
        on_components=None if timer is None else timer.instrument,
    )
    wall = time.perf_counter() - started
    return PeerFigure(name, wall, result.simulated_s)


def time_world_only(scenario: Scenario, config: RoverConfig, simulated_s: float) -> PeerFigure:
    """The simulated world and peers alone for ``simulated_s``, with nobody on the rover's side."""
    from firmware_bridge.vesc import VescCodec
    from firmware_bridge.vesc_dbc import load_vesc_database
    from hil.world import SimWorld

    clock = SimClock()
    dt_s = seconds(PHYSICS_DT_NS)
    with lockstep_wires(config.can, clock=clock) as wires:
        codec = VescCodec(load_vesc_database(config.vesc.controller_ids), config.vesc)
        world = SimWorld(
            scenario,
            config.vehicle,
            codec,
            clock,
            wires.sim_bus,
            wires.sim_mavlink,
            _NullSink(),
            scenario.seed,
        )
        end_ns = to_ns(simulated_s)
        started = time.perf_counter()
        while clock.now_ns() < end_ns:
            clock.advance(PHYSICS_DT_NS)
            world.tick(dt_s)
            # Nobody reads the rover's end: drain it as the onboard would, so queues stay short.
            while wires.onboard_bus.recv(timeout=0) is not None:
                pass
            wires.onboard_mavlink.read()
        wall = time.perf_counter() - started
    return PeerFigure("world-only", wall, seconds(clock.now_ns()))


@dataclass(frozen=True)
class BenchReport:
    scenario: str
    cpu: int | None
    zenoh: bool
    peers: tuple[PeerFigure, ...]
    breakdown_s: dict[str, float]
    breakdown_calls: dict[str, int]
    instrumented_wall_s: float
    metrics_s: float
    simulated_s: float

    def as_dict(self) -> dict[str, Any]:
        loop = sum(self.breakdown_s.values())
        return {
            "benchmark": "hil",
            "scenario": self.scenario,
            "cpu": self.cpu,
            "zenoh": self.zenoh,
            "simulated_s": round(self.simulated_s, 3),
            "real_time_factor": {p.name: round(p.real_time_factor, 2) for p in self.peers},
            "wall_s": {p.name: round(p.wall_s, 3) for p in self.peers},
            "goal_real_time_factor": 50.0,
            "breakdown": {
                name: {
                    "seconds": round(value, 4),
                    "share_pct": round(100.0 * value / loop, 1) if loop > 0 else 0.0,
                    "calls": self.breakdown_calls.get(name, 0),
                    "what": COMPONENT_LABELS.get(name, name),
                }
                for name, value in sorted(self.breakdown_s.items(), key=lambda item: -item[1])
            },
            "metrics_from_mcap_s": round(self.metrics_s, 4),
            "instrumented_wall_s": round(self.instrumented_wall_s, 3),
        }


def run_bench(
    scenario: Scenario,
    config: RoverConfig,
    *,
    telemetry_factory: Callable[[], tuple[MessageSink | None, Callable[[], None]]],
    one_core: bool = True,
    keep_dir: Path | None = None,
) -> BenchReport:
    """Measure every peer and the breakdown; ``telemetry_factory`` gives (sink or None, closer) per run."""
    cpu = pin_to_one_core() if one_core else None
    work_dir = keep_dir or Path(tempfile.mkdtemp(prefix="rover-bench-hil-"))
    try:
        peers = []
        trial_peers: tuple[tuple[str, CanBackend], ...] = (
            ("lockstep", "lockstep"),
            ("lockstep-virtual-can", "virtual"),
        )
        for name, backend in trial_peers:
            telemetry, close = telemetry_factory()
            try:
                peers.append(
                    time_trial(scenario, config, work_dir, name, telemetry=telemetry, can_backend=backend)
                )
            finally:
                close()
        peers.append(time_world_only(scenario, config, peers[0].simulated_s))

        timer = ExclusiveTimer()
        telemetry, close = telemetry_factory()
        try:
            instrumented = time_trial(
                scenario, config, work_dir, "instrumented", telemetry=telemetry, timer=timer
            )
        finally:
            close()
        started = time.perf_counter()
        compute_metrics(work_dir / "lockstep" / "trial.mcap")
        metrics_s = time.perf_counter() - started
        zenoh = telemetry is not None
    finally:
        if keep_dir is None:
            shutil.rmtree(work_dir, ignore_errors=True)
    return BenchReport(
        scenario=scenario.name,
        cpu=cpu,
        zenoh=zenoh,
        peers=tuple(peers),
        breakdown_s=dict(timer.totals_s),
        breakdown_calls=dict(timer.calls),
        instrumented_wall_s=instrumented.wall_s,
        metrics_s=metrics_s,
        simulated_s=peers[0].simulated_s,
    )
