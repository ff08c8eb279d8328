"""``rover bench hil``: the real-time factor of a full lockstep trial, per-component time, and its peers.

Measured in one run, on the same scenario and seed:

* ``lockstep``: the full trial as ``rover hil trial`` runs it (CAN, MAVLink, estimator, planner, follower,
  MCAP, Zenoh when enabled, metrics at the end). The headline figure.
* ``lockstep-virtual-can``: the same with python-can's own ``virtual`` bus between the rover and the
  simulated controllers instead of ``hil.lockstep_bus`` (the walking skeleton's wiring).
* ``world-only``: the simulated world and its peers without the onboard stack, recording to nowhere; the
  ceiling the simulator alone allows.

Each round also times a fixed pure-Python workload (``hil.host_probe``) just before its lockstep trial:
when the trials' times spread and the probe's spread alike, the host's speed moved, not the code's.

Before anything is timed, a short warm-up trial (``WARMUP_S`` simulated seconds of the same scenario)
pays the one-time costs a long-running process pays once: imports done lazily, the numba kernels loaded
from their cache (or compiled, after a source change: tens of seconds that once landed in the first
peer's figure), the Zenoh session's first publishers. Each peer reports wall time and the process's CPU
time (every thread, Zenoh's included): on a shared machine the CPU figure is the steadier one.

The named baselines beside the peers are figures measured elsewhere (issue #6), not in this run; they
give the real-time factor its scale.

The per-component breakdown comes from a separate instrumented run: each component's entry points are
wrapped with a timer that subtracts the time spent in nested timed calls, so the shares are exclusive
and add up to the loop. Wall time via ``time.perf_counter`` (benchmarks may read it; components never do).
"""

from __future__ import annotations

import dataclasses
import functools
import os
import platform
import shutil
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.host_probe import time_host_probe
from hil.lockstep import CanBackend, lockstep_wires
from hil.scenario import Scenario
from hil.trial import PHYSICS_DT_NS, run_trial
from logs.clock import SimClock, seconds, to_ns
from logs.metrics import compute_metrics
from logs.sink import MessageSink
from navigator.config import RoverConfig

WARMUP_S = 3.0
GOAL_REAL_TIME_FACTOR = 50.0
# Reference points from issue #6 (measured elsewhere, not by this benchmark): name -> (low, high) factor.
NAMED_BASELINES: dict[str, tuple[float, float]] = {
    "plain combined loop (issue #6)": (12.0, 15.0),
    "Gazebo rover sims (issue #6)": (0.0, 1.0),
}

# component name -> methods timed on it
TIMED_METHODS: dict[str, tuple[str, ...]] = {
    "onboard": ("step", "set_goal"),
    "can_link": ("poll", "send_wheel_speeds"),
    "mavlink_link": ("poll", "send_heartbeat"),
    "encoding": ("publish",),
    # publish_bytes: the fan-out's bytes (logs.encoding.BytesSink); publish_bytes_many: the CAN link's frame
    # records, one call per poll or command round.
    "recorder": ("publish", "publish_encoded", "publish_bytes", "publish_bytes_many"),
    "telemetry": ("publish", "publish_encoded", "publish_bytes", "publish_bytes_many"),
    "world": ("tick",),
    "vescs": ("poll", "step"),
    "autopilot": ("step", "poll"),
    "dynamics": ("step",),
    "truth": ("on_step",),
}
# What each timed component stands for in the report.
COMPONENT_LABELS = {
    "onboard": "onboard stack (estimator, planner, follower, safety)",
    "can_link": "CAN link (onboard: encode, decode, bus)",
    "mavlink_link": "MAVLink link (onboard: parse, record raw)",
    "encoding": "JSON encoding (once, for MCAP and Zenoh)",
    "recorder": "MCAP recording (+ JSON when Zenoh is off)",
    "telemetry": "Zenoh telemetry (rate limits, put)",
    "world": "sim world glue (faults, battery, obstacles)",
    "vescs": "simulated VESCs (status frames, bus)",
    "autopilot": "simulated autopilot (sensors, MAVLink)",
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
    _names: list[str] = field(default_factory=list)  # per open call: its component

    def wrap(self, name: str, method: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(method)
        def timed(*args: Any, **kwargs: Any) -> Any:
            self._stack.append([0.0])
            self._names.append(name)
            started = time.perf_counter()
            try:
                return method(*args, **kwargs)
            finally:
                elapsed = time.perf_counter() - started
                children = self._stack.pop()[0]
                self._names.pop()
                self.totals_s[name] = self.totals_s.get(name, 0.0) + elapsed - children
                # One component calling its own timed method (publish -> publish_encoded) is one call.
                if not self._names or self._names[-1] != name:
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
    cpu_s: float = 0.0  # process CPU time, all threads
    runs_wall_s: tuple[float, ...] = ()  # each repeat's wall time, when this is their median

    @classmethod
    def median_of(cls, runs: list[PeerFigure]) -> PeerFigure:
        """One figure for repeated runs of a peer: the median wall and CPU time, every wall time kept."""
        return cls(
            runs[0].name,
            statistics.median(r.wall_s for r in runs),
            runs[0].simulated_s,
            statistics.median(r.cpu_s for r in runs),
            tuple(r.wall_s for r in runs),
        )

    @property
    def real_time_factor(self) -> float:
        return self.simulated_s / self.wall_s if self.wall_s > 0 else float("inf")

    @property
    def cpu_real_time_factor(self) -> float:
        return self.simulated_s / self.cpu_s if self.cpu_s > 0 else float("inf")


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
    cpu_started = time.process_time()
    result = run_trial(
        scenario,
        config,
        out_dir,
        telemetry=telemetry,
        can_backend=can_backend,
        on_components=None if timer is None else timer.instrument,
    )
    wall = time.perf_counter() - started
    return PeerFigure(name, wall, result.simulated_s, time.process_time() - cpu_started)


def time_world_only(scenario: Scenario, config: RoverConfig, simulated_s: float) -> PeerFigure:
    """The simulated world and peers alone for ``simulated_s``, with nobody on the rover's side."""
    from firmware_bridge.vesc import VescCodec
    from hil.world import SimWorld

    clock = SimClock()
    dt_s = seconds(PHYSICS_DT_NS)
    with lockstep_wires(config.can, clock=clock) as wires:
        codec = VescCodec.for_profile(config.vesc)
        with SimWorld(
            scenario,
            config.vehicle,
            codec,
            clock,
            wires.sim_bus,
            wires.sim_mavlink,
            _NullSink(),
            scenario.seed,
        ) as world:
            end_ns = to_ns(simulated_s)
            started = time.perf_counter()
            cpu_started = time.process_time()
            while clock.now_ns() < end_ns:
                clock.advance(PHYSICS_DT_NS)
                world.tick(dt_s)
                # Nobody reads the rover's end: drain it as the onboard would, so queues stay short.
                while wires.onboard_bus.recv(timeout=0) is not None:
                    pass
                wires.onboard_mavlink.read()
            wall = time.perf_counter() - started
            cpu = time.process_time() - cpu_started
    return PeerFigure("world-only", wall, seconds(clock.now_ns()), cpu)


def interpreter_facts() -> dict[str, str]:
    """Which Python ran the bench: the same code runs faster on an interpreter built with profile-guided and
    link-time optimization (a distribution's python3) than on one built without (pyenv's default); docs/hil.md
    has both on the build VM."""
    return {
        "version": platform.python_version(),
        "implementation": platform.python_implementation(),
        "executable": os.path.realpath(getattr(sys, "_base_executable", sys.executable)),
        "compiler": platform.python_compiler(),
        "build": " ".join(platform.python_build()),
    }


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
    warmup_s: float = 0.0
    host_probe_s: tuple[float, ...] = ()  # the fixed workload's wall time, once per round (hil.host_probe)

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
            "cpu_real_time_factor": {p.name: round(p.cpu_real_time_factor, 2) for p in self.peers},
            "cpu_s": {p.name: round(p.cpu_s, 3) for p in self.peers},
            "runs_wall_s": {p.name: [round(w, 3) for w in p.runs_wall_s] for p in self.peers},
            "goal_real_time_factor": GOAL_REAL_TIME_FACTOR,
            "named_baselines": {name: list(span) for name, span in NAMED_BASELINES.items()},
            "warmup_wall_s": round(self.warmup_s, 3),
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
            "host_probe_s": [round(wall, 4) for wall in self.host_probe_s],
            "python": interpreter_facts(),
        }


def run_bench(
    scenario: Scenario,
    config: RoverConfig,
    *,
    telemetry_factory: Callable[[], tuple[MessageSink | None, Callable[[], None]]],
    one_core: bool = True,
    keep_dir: Path | None = None,
    repeats: int = 1,
) -> BenchReport:
    """Measure every peer and the breakdown; ``telemetry_factory`` gives (sink or None, closer) per run.

    ``repeats``: each peer is timed this many times, in interleaved rounds (every peer once per round, so
    a noisy stretch of the machine hits them alike); the figure is the median (``PeerFigure.median_of``).
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    cpu = pin_to_one_core() if one_core else None
    work_dir = keep_dir or Path(tempfile.mkdtemp(prefix="rover-bench-hil-"))
    try:
        warmup_s = _warm_up(scenario, config, work_dir, telemetry_factory)
        trial_peers: tuple[tuple[str, CanBackend], ...] = (
            ("lockstep", "lockstep"),
            ("lockstep-virtual-can", "virtual"),
        )
        rounds: list[list[PeerFigure]] = []
        host_probe_s: list[float] = []
        for _ in range(repeats):
            host_probe_s.append(time_host_probe())
            figures = []
            for name, backend in trial_peers:
                telemetry, close = telemetry_factory()
                try:
                    figures.append(
                        time_trial(scenario, config, work_dir, name, telemetry=telemetry, can_backend=backend)
                    )
                finally:
                    close()
            figures.append(time_world_only(scenario, config, figures[0].simulated_s))
            rounds.append(figures)
        peers = [PeerFigure.median_of([r[i] for r in rounds]) for i in range(len(rounds[0]))]

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
        warmup_s=warmup_s,
        host_probe_s=tuple(host_probe_s),
    )


def _warm_up(
    scenario: Scenario,
    config: RoverConfig,
    work_dir: Path,
    telemetry_factory: Callable[[], tuple[MessageSink | None, Callable[[], None]]],
) -> float:
    """A short untimed trial, so no peer's figure carries the process's one-time costs; its wall time."""
    short = dataclasses.replace(scenario, duration_s=min(WARMUP_S, scenario.duration_s))
    telemetry, close = telemetry_factory()
    try:
        return time_trial(short, config, work_dir, "warm-up", telemetry=telemetry).wall_s
    finally:
        close()
