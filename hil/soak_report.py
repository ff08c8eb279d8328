"""Judging a soak from its recordings: each fault injected, seen on the rover and recovered from; memory
growth; ticks and overruns; crashes.

Times: both recordings carry the OS monotonic clock (``rover run`` and ``rover hil peer`` both use
``MonotonicClock``), so the peer's ``fault injected`` / ``fault cleared`` records (``hil.faults``) and the
rover's ``safety/events`` and ``runtime/timing`` line up directly. The e-stop's times come from the soak.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hil.soak_plan import DEADLINE_TICKS, SoakFault
from logs import topics
from logs.reader import read_messages, read_metadata

NS = 1_000_000_000
SEEN_SLACK_S = 3.0  # a failsafe may fire this long after its fault ended (the tick that judges it)
RECOVER_LIMIT_S = 15.0  # after the fault ends, it must have cleared within this
_FAULT_LOG = re.compile(r"fault (injected|cleared): (\S+)")


@dataclass(frozen=True)
class ProcessRun:
    name: str
    rss_kb: list[tuple[float, int]]  # (seconds from the soak's start, resident set KiB)
    crashed_at_s: float | None  # it exited before the soak stopped it
    returncode: int | None
    tracebacks: int  # "Traceback" blocks in its log


@dataclass(frozen=True)
class FaultResult:
    name: str
    start_s: float
    end_s: float
    injected: bool
    seen: bool
    recovered: bool
    evidence: str  # what was looked for and what was found


@dataclass(frozen=True)
class MemoryResult:
    name: str
    start_mb: float
    end_mb: float
    max_mb: float
    slope_mb_per_min: float  # least-squares fit over the samples after the warm-up


@dataclass
class SoakReport:
    seconds: float
    seed: int
    faults: list[FaultResult]
    memory: list[MemoryResult]
    ticks: int
    sensor_ticks: int
    deadline_ticks: int
    overruns: int
    crashes: list[str]
    failsafe_events: dict[str, int] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.crashes and all(f.injected and f.seen and f.recovered for f in self.faults)

    def to_json(self) -> str:
        return json.dumps({**asdict(self), "ok": self.ok}, indent=2, default=_json_default)


def _json_default(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    raise TypeError(f"not JSON: {value!r}")


def judge_soak(
    seconds: float,
    seed: int,
    plan: list[SoakFault],
    epoch_s: float,
    estops: list[tuple[float, float]],
    runs: list[ProcessRun],
    rover_mcap: Path,
    truth_mcap: Path,
    warmup_s: float,
) -> SoakReport:
    """The report of one soak (``epoch_s``: the soak's time zero on the monotonic clock, seconds)."""
    windows = _fault_windows(truth_mcap) if truth_mcap.exists() else {}
    estop_windows = [(start * NS + epoch_s * NS, end * NS + epoch_s * NS) for start, end in estops]
    events = _events(rover_mcap) if rover_mcap.exists() else []
    timing = _timing(rover_mcap) if rover_mcap.exists() else []
    results = []
    for fault in plan:
        if fault.target == "estop":
            window = estop_windows.pop(0) if estop_windows else None
        else:
            found = windows.get(fault.name, [])
            window = found.pop(0) if found else None
        results.append(_judge_fault(fault, window, events, timing, epoch_s))
    totals = _totals(rover_mcap) if rover_mcap.exists() else {}
    crashes = []
    for run in runs:
        if run.crashed_at_s is not None:
            crashes.append(f"{run.name} exited ({run.returncode}) at {run.crashed_at_s:.1f} s")
        elif run.returncode not in (0, None):
            crashes.append(f"{run.name} ended with exit code {run.returncode}")
        if run.tracebacks:
            crashes.append(f"{run.name} logged {run.tracebacks} traceback(s)")
    fired: dict[str, int] = {}
    for _, kind in events:
        if kind.startswith("failsafe."):
            fired[kind] = fired.get(kind, 0) + 1
    return SoakReport(
        seconds=seconds,
        seed=seed,
        faults=results,
        memory=[_memory(run, warmup_s) for run in runs],
        ticks=int(totals.get("ticks", 0)),
        sensor_ticks=int(totals.get("sensor_ticks", 0)),
        deadline_ticks=int(totals.get("deadline_ticks", 0)),
        overruns=int(totals.get("overruns", 0)),
        crashes=crashes,
        failsafe_events=fired,
    )


def _judge_fault(
    fault: SoakFault,
    window: tuple[float, float] | None,
    events: list[tuple[int, str]],
    timing: list[tuple[int, dict[str, Any]]],
    epoch_s: float,
) -> FaultResult:
    planned = (fault.start_s, fault.end_s)
    if window is None or not math.isfinite(window[1]):
        return FaultResult(fault.name, *planned, False, False, False, "never injected (or never ended)")
    start, end = int(window[0]), int(window[1])
    at = ((start / NS) - epoch_s, (end / NS) - epoch_s)
    if fault.evidence == DEADLINE_TICKS:
        during = [m for t, m in timing if start + NS <= t <= end + NS // 2]
        seen = any(m["deadline_ticks"] > 0 for m in during)
        after = [m for t, m in timing if end + NS < t <= end + RECOVER_LIMIT_S * NS]
        recovered = any(m["ticks"] > 0 and m["sensor_ticks"] >= 0.8 * m["ticks"] for m in after)
        detail = f"deadline ticks in {sum(m['deadline_ticks'] for m in during)} of the silent window's ticks"
        return FaultResult(fault.name, *at, True, seen, recovered, detail)
    raised, lowered = f"failsafe.{fault.failsafe}", f"cleared.{fault.failsafe}"
    fired = [t for t, kind in events if kind == raised and start <= t <= end + SEEN_SLACK_S * NS]
    # Already raised when the fault began (the same failsafe, for another cause: all controllers silent
    # through a stall of the peer just then) and not cleared before it: the rover is holding for it.
    holding = _active_at(events, raised, lowered, start)
    if holding is not None:
        fired = [holding]
    if not fired:
        return FaultResult(fault.name, *at, True, False, False, f"no {raised}")
    cleared = [t for t, kind in events if kind == lowered and fired[0] < t <= end + RECOVER_LIMIT_S * NS]
    when = "after" if fired[0] >= start else "before"
    detail = f"{raised} {abs(fired[0] - start) / NS:.2f} s {when} the start"
    if cleared:
        detail += f", cleared {(cleared[0] - end) / NS:.2f} s after the end"
    return FaultResult(fault.name, *at, True, True, bool(cleared), detail)


def _active_at(events: list[tuple[int, str]], raised: str, lowered: str, t_ns: int) -> int | None:
    """When the failsafe active at ``t_ns`` was raised (events in time order), or None if it was not."""
    since = None
    for t, kind in events:
        if t >= t_ns:
            break
        if kind == raised:
            since = t
        elif kind == lowered:
            since = None
    return since


def _fault_windows(truth_mcap: Path) -> dict[str, list[tuple[float, float]]]:
    """Fault name -> [(injected ns, cleared ns)] in order, from the peer's ``log`` records."""
    windows: dict[str, list[tuple[float, float]]] = {}
    for message in read_messages(truth_mcap, [topics.LOG]):
        match = _FAULT_LOG.match(str(message.message.get("message", "")))
        if message.message.get("name") != "hil.faults" or match is None:
            continue
        what, name = match.groups()
        entries = windows.setdefault(name, [])
        if what == "injected":
            entries.append((float(message.log_time_ns), math.inf))
        elif entries and not math.isfinite(entries[-1][1]):
            entries[-1] = (entries[-1][0], float(message.log_time_ns))
    return windows


def _events(rover_mcap: Path) -> list[tuple[int, str]]:
    return [
        (m.log_time_ns, str(m.message["kind"])) for m in read_messages(rover_mcap, [topics.SAFETY_EVENTS])
    ]


def _timing(rover_mcap: Path) -> list[tuple[int, dict[str, Any]]]:
    return [(m.log_time_ns, m.message) for m in read_messages(rover_mcap, [topics.RUNTIME_TIMING])]


def _totals(rover_mcap: Path) -> dict[str, Any]:
    runtime = read_metadata(rover_mcap).get("runtime")
    if runtime is None:  # the rover did not shut down cleanly: add up the timing windows
        windows = [m for _, m in _timing(rover_mcap)]
        keys = ("ticks", "sensor_ticks", "deadline_ticks", "overruns")
        return {key: sum(int(w[key]) for w in windows) for key in keys}
    return dict(json.loads(runtime["timing_json"]))


def _memory(run: ProcessRun, warmup_s: float) -> MemoryResult:
    samples = run.rss_kb
    if not samples:
        return MemoryResult(run.name, math.nan, math.nan, math.nan, math.nan)
    mb = [(t, kb / 1024.0) for t, kb in samples]
    settled = [(t, m) for t, m in mb if t >= warmup_s] or mb
    slope = math.nan
    if len(settled) >= 3:
        times = np.array([t for t, _ in settled]) / 60.0
        values = np.array([m for _, m in settled])
        slope = float(np.polyfit(times, values, 1)[0])
    return MemoryResult(run.name, mb[0][1], mb[-1][1], max(m for _, m in mb), slope)
