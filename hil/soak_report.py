"""Judging a soak from its recordings: each fault injected, seen on the rover and recovered from; memory
growth; ticks and overruns; the peer's stalls; failsafes no planned fault explains; crashes.

Not OK (``SoakReport.problems``): a crash; a fault not injected, seen or recovered; any failsafe that
neither a planned fault explains (``hil.soak_plan.RAISES``: what each fault may raise, from its start
until ``SEEN_SLACK_S`` after its end) nor a recorded stall of the peer accounts for (``stall_accounts_for``:
the stall's silence covers the failsafe's own budget); a stall of the peer (the real time between two of
its steps) longer than the simulated controllers' command timeout (``PEER_STALL_LIMIT_MS``): beyond it the
controllers stop the wheels by themselves, and the soak tests the machine's scheduler, not the rover.
Only stalls from the soak's time zero (the rover's first wheel command) are judged: before it the peer
held its scenario while ``rover run`` came up, and nothing drove on its steps (they are counted apart).

A silent IMU (the pacing sensor) is judged from ``runtime/timing``, one window per second, against the
rover's own pace just before it: seen when a whole window inside the fault ran on the deadline alone, and
recovered when a whole window after it was sensor-paced again at ``RECOVERED_SHARE`` of that pace. On a
busy host the rover is sensor-paced only part of the time, so a fixed share would fail a rover that
recovered, and "some deadline ticks" would see a fault that the rover never noticed.

Times: both recordings carry the OS monotonic clock (``rover run`` and ``rover hil peer`` both use
``MonotonicClock``), so the peer's ``fault injected`` / ``fault cleared`` records (``hil.faults``) and the
rover's ``safety/events`` and ``runtime/timing`` line up directly. The e-stop's times come from the soak.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from hil.peer_stalls import parse_stall_message
from hil.soak_plan import DEADLINE_TICKS, SoakFault
from hil.vesc_sim import DEFAULT_COMMAND_TIMEOUT_S
from logs import topics
from logs.reader import read_messages, read_metadata
from navigator.safety_config import SafetyConfig

NS = 1_000_000_000
SEEN_SLACK_S = 3.0  # a failsafe may fire this long after its fault ended (the tick that judges it)
RECOVER_LIMIT_S = 15.0  # after the fault ends, it must have cleared within this
LEAD_SLACK_S = 0.1  # a failsafe this long before its fault's recorded start still counts (e-stop send time)
PEER_STALL_LIMIT_MS = DEFAULT_COMMAND_TIMEOUT_S * 1000.0
STALL_HINT_S = 1.0  # a peer stall this long before an unexplained failsafe is named beside it
# A peer stall shorter than PEER_STALL_LIMIT_MS is the machine's and accepted; what it silences is too. Of
# the rover's failsafes only wheel_silent has a budget that short (docs/safety.md: GPS and heartbeat 3 s,
# the AHRS attitude 1 s: a stall of 0.5 s and one 0.1 s attitude period fall well short of it).
WHEEL_SILENT_S = SafetyConfig().wheel_silent_s  # the soak's rover keeps the default
STATUS_PERIOD_S = 0.02  # the simulated controllers' STATUS period (hil.vesc_sim: 50 Hz)
# After a stall the rover hears status again within this: the catch-up step's send, the UDP hop, one tick.
STALL_DELIVERY_S = 0.05
BASELINE_S = 5.0  # a silent IMU's "before": the rover's sensor-paced share over this long before it
IMU_GRACE_S = 0.1  # a window inside a silent IMU starts this long after it (samples already in flight)
RECOVERED_SHARE = 0.8  # of the share before the fault, in one whole window after it
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


@dataclass(frozen=True)
class PeerTiming:
    """The real-time peer's own timing (``hil.peer``): its scheduler's skipped ticks and its stalls."""

    overruns: int | None  # None: the peer wrote no summary (it did not stop cleanly)
    stalls: int  # steps later than the peer integrates in one go
    dropped_sim_ms: float  # the simulated time those stalls dropped
    longest_step_gap_ms: float | None  # real time between two steps; None: unknown
    # The stalls above before the soak's time zero, while the peer held its scenario for `rover run` to
    # come up (hil.peer_start): its first steps on a cold numba cache compile for seconds. No rover drove
    # on the peer's steps then, so they are not judged.
    stalls_before_start: int = 0
    # The longest gap of a stall from the soak's time zero on: the one judged (PEER_STALL_LIMIT_MS); None:
    # no stall then (every gap within the peer's catch-up, PeerStalls.cap_ns).
    longest_soak_stall_ms: float | None = None

    @classmethod
    def unknown(cls) -> PeerTiming:
        return cls(None, 0, 0.0, None)


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
    peer: PeerTiming = field(default_factory=PeerTiming.unknown)
    unexplained_failsafes: list[str] = field(default_factory=list)  # each with its time and detail
    # Failsafes a recorded peer stall accounts for (the machine's, not the stack's), with the stall.
    stall_failsafes: list[str] = field(default_factory=list)
    # When the rover's control loop first ran, from the soak's time zero (the rover's first wheel command,
    # so about 0, a little below it if the loop ticked before it commanded); None: never.
    rover_first_tick_s: float | None = None
    peer_scheduling: str = "normal scheduling"  # what `rover hil peer --fifo` got (its `scheduling:` line)

    @property
    def problems(self) -> list[str]:
        """Why the soak is not OK, in words; empty when it is."""
        problems = list(self.crashes)
        for f in self.faults:
            checks = (("injected", f.injected), ("seen", f.seen), ("recovered", f.recovered))
            missing = [word for word, held in checks if not held]
            if missing:
                problems.append(
                    f"fault {f.name} at {f.start_s:.1f} s not {' / '.join(missing)}: {f.evidence}"
                )
        problems += [f"unexplained {failsafe}" for failsafe in self.unexplained_failsafes]
        gap = self.peer.longest_soak_stall_ms
        if gap is not None and gap > PEER_STALL_LIMIT_MS:
            problems.append(
                f"the peer stalled {gap:.0f} ms between two steps, longer than the simulated controllers' "
                f"command timeout ({PEER_STALL_LIMIT_MS:.0f} ms)"
            )
        return problems

    @property
    def ok(self) -> bool:
        return not self.problems

    def to_json(self) -> str:
        return json.dumps(
            {**asdict(self), "ok": self.ok, "problems": self.problems}, indent=2, default=_json_default
        )


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
    peer, stalls = _peer_timing(truth_mcap, epoch_s) if truth_mcap.exists() else (PeerTiming.unknown(), [])
    results = []
    placed: list[tuple[SoakFault, tuple[float, float] | None]] = []
    first_tick_s = _first_tick_s(timing, epoch_s)
    for fault in plan:
        if fault.target == "estop":
            window = estop_windows.pop(0) if estop_windows else None
        else:
            found = windows.get(fault.name, [])
            window = found.pop(0) if found else None
        placed.append((fault, window))
        results.append(_too_early(_judge_fault(fault, window, events, timing, epoch_s), first_tick_s))
    failsafes = _failsafes(rover_mcap) if rover_mcap.exists() else []
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
        peer=peer,
        unexplained_failsafes=unexplained_failsafes(failsafes, placed, stalls, epoch_s),
        stall_failsafes=stall_failsafes(failsafes, stalls, epoch_s),
        rover_first_tick_s=first_tick_s,
    )


def _first_tick_s(timing: list[tuple[int, dict[str, Any]]], epoch_s: float) -> float | None:
    """When the rover's loop first ticked (s from the epoch), from its first ``runtime/timing`` window
    with ticks: the window's end less its ticks at the nominal period (the window itself may start at
    the publisher's construction, before the warm-up)."""
    for t_ns, m in timing:
        if m["ticks"] > 0:
            return t_ns / NS - epoch_s - m["ticks"] * m["nominal_period_ms"] / 1000.0
    return None


def _too_early(result: FaultResult, first_tick_s: float | None) -> FaultResult:
    """A fault not seen or not recovered that began before the rover's loop ran says so: the soak's
    warm-up was too short for this machine, and the rover could not have seen it (nor had a pace before
    it to recover to)."""
    if (result.seen and result.recovered) or not result.injected:
        return result
    if first_tick_s is not None and result.start_s >= first_tick_s:
        return result
    if first_tick_s is None:
        return replace(result, evidence=f"{result.evidence}; the rover's control loop never ran")
    evidence = (
        f"{result.evidence}; the rover's control loop first ran at {first_tick_s:.1f} s, after it began"
    )
    return replace(result, evidence=evidence)


def unexplained_failsafes(
    failsafes: list[tuple[int, str, str]],
    placed: list[tuple[SoakFault, tuple[float, float] | None]],
    stalls: list[tuple[int, float, float]],
    epoch_s: float,
) -> list[str]:
    """Each failsafe raised (``(ns, "failsafe.<name>", detail)``) that neither a planned fault explains nor
    a stall of the peer accounts for (``stall_failsafes``), in words.

    ``placed``: each planned fault with its window as recorded (ns on the shared clock; None: never
    injected); ``stalls``: the peer's, ``(ns, gap ms, dropped ms)``; a stall shortly before an unexplained
    failsafe, though its silence does not cover the failsafe's budget, is named beside it as a lead.
    """
    unexplained = []
    for t_ns, kind, detail in failsafes:
        name = kind.removeprefix("failsafe.")
        if _stall_behind(t_ns, name, stalls) is not None:
            continue
        if any(
            window is not None
            and name in fault.may_raise
            and window[0] - LEAD_SLACK_S * NS <= t_ns <= window[1] + SEEN_SLACK_S * NS
            for fault, window in placed
        ):
            continue
        text = f"{kind} at {t_ns / NS - epoch_s:.1f} s ({detail})"
        before = [s for s in stalls if t_ns - STALL_HINT_S * NS <= s[0] <= t_ns]
        if before:
            at, gap_ms, _dropped = max(before, key=lambda s: s[1])
            text += f"; the peer stalled {gap_ms:.0f} ms between steps at {at / NS - epoch_s:.1f} s"
        unexplained.append(text)
    return unexplained


def stall_failsafes(
    failsafes: list[tuple[int, str, str]], stalls: list[tuple[int, float, float]], epoch_s: float
) -> list[str]:
    """Each failsafe that a recorded stall of the peer accounts for (``stall_accounts_for``), in words."""
    explained = []
    for t_ns, kind, detail in failsafes:
        stall = _stall_behind(t_ns, kind.removeprefix("failsafe."), stalls)
        if stall is not None:
            at, gap_ms, _dropped = stall
            explained.append(
                f"{kind} at {t_ns / NS - epoch_s:.1f} s ({detail}): the peer stalled {gap_ms:.0f} ms "
                f"between steps at {at / NS - epoch_s:.1f} s"
            )
    return explained


def _stall_behind(
    t_ns: int, name: str, stalls: list[tuple[int, float, float]]
) -> tuple[int, float, float] | None:
    """The recorded stall that accounts for failsafe ``name`` raised at ``t_ns``, if one does."""
    if name != "wheel_silent":
        return None
    return next((s for s in stalls if stall_accounts_for(s, t_ns)), None)


def stall_accounts_for(stall: tuple[int, float, float], t_ns: int) -> bool:
    """Whether a peer stall (``(ns of the step after it, gap ms, dropped ms)``) silenced the controllers
    for the whole budget of a ``wheel_silent`` raised at ``t_ns``.

    The frozen peer sent nothing from its last status before the gap (up to one status period before it)
    until the step after it, which the rover hears within ``STALL_DELIVERY_S``; the failsafe says nothing
    was heard over the ``WHEEL_SILENT_S`` before ``t_ns``. The stall accounts for it only if that silence
    lies within the stall's: a failsafe later than the delivery, or a gap too short to cover the budget,
    had a silence the stall does not explain (the stack's, or a stall of the rover itself).
    """
    end_ns, gap_ms, _dropped = stall
    silent_from = end_ns - (gap_ms / 1000.0 + STATUS_PERIOD_S) * NS
    return silent_from <= t_ns - WHEEL_SILENT_S * NS and t_ns <= end_ns + STALL_DELIVERY_S * NS


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
        seen, recovered, detail = _judge_silent_imu(start, end, timing)
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


def _judge_silent_imu(
    start: int, end: int, timing: list[tuple[int, dict[str, Any]]]
) -> tuple[bool, bool, str]:
    """(seen, recovered, evidence) of a silent IMU from the rover's ``runtime/timing`` windows."""
    windows = [(t - round(m["window_s"] * NS), t, m) for t, m in timing if m["ticks"] > 0]
    before = [m for s, t, m in windows if start - BASELINE_S * NS <= s and t <= start]
    during = [m for s, t, m in windows if start + IMU_GRACE_S * NS <= s and t <= end]
    after = [m for s, t, m in windows if end <= s and t <= end + RECOVER_LIMIT_S * NS]
    # No window before it (the rover had only just started): no pace of its own to hold it to, so the
    # fixed share of a quiet host.
    share_before = _sensor_share(before) if before else 1.0
    seen = share_before > 0.0 and any(m["sensor_ticks"] == 0 for m in during)
    best_after = max((_sensor_share([m]) for m in after), default=0.0)
    # Recovered: some window after it sensor-paced at all (its share > 0: every window here has ticks) and
    # at RECOVERED_SHARE of the pace before; the best window is that one if any is.
    recovered = best_after > 0.0 and best_after >= RECOVERED_SHARE * share_before
    silent = min((m["sensor_ticks"] for m in during), default=None)
    detail = (
        f"sensor-paced {share_before:.0%} of ticks before; "
        + ("no whole window inside the fault" if silent is None else f"fewest in a window during: {silent}")
        + f"; best window after: {best_after:.0%} (needs {RECOVERED_SHARE * share_before:.0%})"
    )
    return seen, recovered, detail


def _sensor_share(windows: list[dict[str, Any]]) -> float:
    ticks = sum(int(m["ticks"]) for m in windows)
    return sum(int(m["sensor_ticks"]) for m in windows) / ticks if ticks else 0.0


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


def _peer_timing(truth_mcap: Path, epoch_s: float) -> tuple[PeerTiming, list[tuple[int, float, float]]]:
    """The peer's timing summary and its stalls ``(ns, gap ms, dropped ms)`` from its recording.

    The stalls come from its ``log`` records, so they are there even if the peer was killed; the summary
    (overruns, longest gap) only if it stopped cleanly, else it is rebuilt from the stalls it recorded.
    Those before ``epoch_s`` (the soak's time zero) are told apart: the peer was holding its scenario.
    """
    stalls = []
    for message in read_messages(truth_mcap, [topics.LOG]):
        parsed = parse_stall_message(str(message.message.get("message", "")))
        if message.message.get("name") == "hil.peer" and parsed is not None:
            stalls.append((message.log_time_ns, *parsed))
    runtime = read_metadata(truth_mcap).get("runtime", {})
    if "timing_json" in runtime and "stalls_json" in runtime:
        timing, summary = json.loads(runtime["timing_json"]), json.loads(runtime["stalls_json"])
        peer = PeerTiming(
            int(timing["overruns"]),
            int(summary["stalls"]),
            float(summary["dropped_sim_ms"]),
            float(summary["longest_step_gap_ms"]),
        )
    else:
        gaps = [gap for _, gap, _ in stalls]
        peer = PeerTiming(None, len(stalls), sum(d for _, _, d in stalls), max(gaps) if gaps else None)
    # A stall is recorded on the step after it: one that ended at or after time zero is the soak's.
    in_soak = [gap for t_ns, gap, _ in stalls if t_ns >= epoch_s * NS]
    peer = replace(
        peer,
        stalls_before_start=len(stalls) - len(in_soak),
        longest_soak_stall_ms=max(in_soak, default=None),
    )
    return peer, stalls


def _failsafes(rover_mcap: Path) -> list[tuple[int, str, str]]:
    return [
        (m.log_time_ns, str(m.message["kind"]), str(m.message.get("detail", "")))
        for m in read_messages(rover_mcap, [topics.SAFETY_EVENTS])
        if str(m.message["kind"]).startswith("failsafe.")
    ]


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
