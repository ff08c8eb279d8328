"""``rover hil soak``: real-time HIL for minutes with faults sprinkled in; crashes, recovery and memory.

Two real processes, as in the real-time system tests: ``rover hil peer`` (the simulated rover, applying
the seeded fault schedule of ``hil.soak_plan``) and ``rover run`` (the onboard stack), on python-can
``udp_multicast`` inside the private network namespace (``scripts/in-private-netns``) or on ``vcan0``,
MAVLink on UDP 127.0.0.1. The soak itself is the ground station: over Zenoh on loopback (multicast
scouting off) it sends patrol goals and the e-stop / resume of the plan. Every ``rss_period_s`` it reads
both processes' resident memory from ``/proc``. At the end it stops both with SIGINT and judges the
recordings (``hil.soak_report``).

The peer holds its scenario until the rover's first wheel command (``rover hil peer --start-on-command``,
``hil.peer_start``): ``rover run`` may take 5-45 s to come up (a cold numba cache compiles for 30-45 s),
and a fault timed from the peer's start could run its course before the rover existed. The soak's time
zero is that first command, which the peer writes in its status file; the plan's faults (the peer's and
the soak's own e-stops), the warm-up and the RSS samples count from it.
"""

from __future__ import annotations

import itertools
import json
import logging
import math
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from firmware_bridge.errors import BridgeSetupError
from firmware_bridge.private_network import require_loopback_only
from hil.soak_plan import PATROL, PATROL_PERIOD_S, SoakFault, fault_plan, scenario_text
from hil.soak_report import ProcessRun, SoakReport, judge_soak
from logs.commands import send_command
from logs.settings import parse_toml
from logs.telemetry import ZenohSettings, open_session

_log = logging.getLogger(__name__)


class SoakSetupError(RuntimeError):
    """The soak cannot start here (no private network namespace, a peer that never came up)."""


START_TIMEOUT_S = 120.0  # the peer's first start may compile numba kernels
# From the peer's start to the rover's first wheel command: `rover run` on a cold numba cache compiles for
# 30-45 s, longer on a loaded host. The peer gives up after it (`--start-timeout`), and so does the soak.
ROVER_START_TIMEOUT_S = 120.0
POLL_S = 0.1


@dataclass(frozen=True)
class SoakSettings:
    seconds: float
    seed: int
    out_dir: Path
    rss_period_s: float = 5.0
    # From the rover's first wheel command (the soak's time zero) to the first fault: estimate settled,
    # driving.
    warmup_s: float = 20.0
    gap_s: tuple[float, float] = (12.0, 20.0)  # recovery time after each fault
    can_interface: str = "udp_multicast"
    can_channel: str | None = None  # default: a fresh multicast group
    # SCHED_FIFO priority of the peer (`rover hil peer --fifo`), 0: normal scheduling. The peer stands for
    # hardware on its own timers; at the normal policy the rover's threads could make it late, and a
    # stall of the peer past the controllers' command timeout measures the machine, not the rover.
    peer_fifo: int = 0


def run_soak(settings: SoakSettings) -> SoakReport:
    """Run the soak; returns the judged report (also written to ``OUT/soak.json``)."""
    if settings.can_interface == "udp_multicast":
        try:
            require_loopback_only("the soak's udp_multicast CAN")
        except BridgeSetupError as err:
            raise SoakSetupError(str(err)) from err
    out = settings.out_dir
    earlier = [path for path in (out / "peer" / "truth.mcap", out / "rover" / "rover.mcap") if path.exists()]
    if earlier:
        # The peer and the rover each refuse to write over a recording; say so here, before anything runs,
        # rather than fail after starting the peer.
        raise SoakSetupError(
            f"{out} holds an earlier soak's recordings ({', '.join(str(p) for p in earlier)}); give another "
            "--out, or remove them"
        )
    out.mkdir(parents=True, exist_ok=True)
    plan = fault_plan(settings.seed, settings.seconds, settings.warmup_s, settings.gap_s)
    scenario = out / "soak-scenario.toml"
    scenario.write_text(scenario_text(f"soak-seed{settings.seed}", settings.seconds, settings.seed, plan))
    channel = settings.can_channel or _multicast_group(settings.seed)
    peer_dir, rover_dir = out / "peer", out / "rover"
    peer_dir.mkdir(exist_ok=True)
    rover_dir.mkdir(exist_ok=True)
    _log.info(
        "soak: %.0f s, seed %d, %d faults; recordings in %s", settings.seconds, settings.seed, len(plan), out
    )
    with open(peer_dir / "peer.log", "wb") as peer_log, open(rover_dir / "rover.log", "wb") as rover_log:
        peer = subprocess.Popen(
            _cli(
                "hil", "peer", str(scenario), "--can-interface", settings.can_interface,
                "--can-channel", channel, "--port-file", str(peer_dir / "port"),
                "--status-file", str(peer_dir / "status.json"), "--out", str(peer_dir),
                "--start-on-command", "--start-timeout", str(ROVER_START_TIMEOUT_S),
                "--duration", str(ROVER_START_TIMEOUT_S + settings.seconds + 60.0),
                *(("--fifo", str(settings.peer_fifo)) if settings.peer_fifo else ()),
            ),
            stdout=peer_log,
            stderr=subprocess.STDOUT,
        )  # fmt: skip
        rover: subprocess.Popen[bytes] | None = None
        try:
            _wait_for_file(peer_dir / "port", peer)
            endpoint = f"tcp/127.0.0.1:{_free_port()}"
            config = _rover_config(peer_dir / "rover-hil.toml", rover_dir / "rover-soak.toml", endpoint)
            goal = PATROL[0]
            rover = subprocess.Popen(
                _cli(
                    "-v",
                    "run",
                    "--config",
                    str(config),
                    "--goal",
                    f"{goal[0]},{goal[1]}",
                    "--out",
                    str(rover_dir),
                ),
                stdout=rover_log,
                stderr=subprocess.STDOUT,
            )
            # The peer's scenario, and every time of the soak's, starts at the rover's first wheel command.
            epoch = _wait_for_scenario_start(peer_dir / "status.json", peer, rover)
            runs, estops = _drive(settings, plan, epoch, endpoint, peer, rover, peer_dir / "status.json")
        finally:
            for process in (rover, peer):
                if process is not None:
                    _stop(process)
    finished = [
        ProcessRun(r.name, r.rss_kb, r.crashed_at_s, _returncode(p), _tracebacks(log))
        for r, p, log in zip(
            runs, (rover, peer), (rover_dir / "rover.log", peer_dir / "peer.log"), strict=True
        )
    ]
    report = judge_soak(
        settings.seconds,
        settings.seed,
        plan,
        epoch,
        estops,
        finished,
        rover_dir / "rover.mcap",
        peer_dir / "truth.mcap",
        settings.warmup_s,
    )
    if settings.peer_fifo:
        report.peer_scheduling = _said_scheduling(peer_dir / "peer.log")
    (out / "soak.json").write_text(report.to_json(), encoding="utf-8")
    return report


def _said_scheduling(peer_log: Path) -> str:
    """What the peer said of its ``--fifo`` priority (``scheduling: ...`` in its log)."""
    try:
        lines = peer_log.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as err:
        return f"unknown (cannot read {peer_log}: {err.strerror or err})"
    said = [line.split("scheduling:", 1)[1].strip() for line in lines if line.startswith("scheduling:")]
    return said[0] if said else "unknown (the peer did not say)"


@dataclass
class _Sampled:
    name: str
    rss_kb: list[tuple[float, int]]
    crashed_at_s: float | None = None


def _drive(
    settings: SoakSettings,
    plan: list[SoakFault],
    epoch: float,
    endpoint: str,
    peer: subprocess.Popen[bytes],
    rover: subprocess.Popen[bytes],
    status_file: Path,
) -> tuple[list[_Sampled], list[tuple[float, float]]]:
    """The soak's own loop: e-stops, patrol goals, RSS samples, crash watch; returns samples and the
    (e-stop, resume) times in seconds from ``epoch``."""
    ground = open_session(_ground_settings(endpoint))
    rover_id = "rover1"
    sampled = [_Sampled("rover", []), _Sampled("peer", [])]
    estop_plan = [f for f in plan if f.target == "estop"]
    estops: list[tuple[float, float]] = []
    patrol = itertools.cycle(PATROL[1:] + PATROL[:1])
    goal, goal_sent_s = PATROL[0], 0.0
    next_rss_s = 0.0
    try:
        while (now_s := time.monotonic() - epoch) < settings.seconds:
            for run, process in zip(sampled, (rover, peer), strict=True):
                if run.crashed_at_s is None and process.poll() is not None:
                    run.crashed_at_s = now_s
                    _log.error("soak: %s exited with %s at %.1f s", run.name, process.returncode, now_s)
            if any(r.crashed_at_s is not None for r in sampled):
                break
            if now_s >= next_rss_s:
                for run, process in zip(sampled, (rover, peer), strict=True):
                    rss = _rss_kb(process.pid)
                    if rss is not None:
                        run.rss_kb.append((now_s, rss))
                next_rss_s += settings.rss_period_s
            if estop_plan and now_s >= estop_plan[0].start_s:
                fault = estop_plan.pop(0)
                send_command(ground, rover_id, "estop")
                estops.append((time.monotonic() - epoch, math.nan))
                _sleep_until(epoch + fault.end_s)
                send_command(ground, rover_id, "resume")
                estops[-1] = (estops[-1][0], time.monotonic() - epoch)
            if _near(status_file, goal) or now_s - goal_sent_s > PATROL_PERIOD_S:
                goal, goal_sent_s = next(patrol), now_s
                send_command(ground, rover_id, "goal", goal[0], goal[1])
            time.sleep(POLL_S)
    finally:
        ground.close()
    return sampled, estops


def _peer_status(status_file: Path) -> dict[str, Any]:
    """The peer's status file ({} while there is none, or no whole one: it is replaced atomically)."""
    try:
        status = json.loads(status_file.read_text(encoding="utf-8"))
    except (FileNotFoundError, ValueError):
        return {}
    return status if isinstance(status, dict) else {}


def _near(status_file: Path, goal: tuple[float, float]) -> bool:
    status = _peer_status(status_file)
    if not status:
        return False
    return bool(math.hypot(status["x_m"] - goal[0], status["y_m"] - goal[1]) < 1.0)


def _rover_config(peer_config: Path, out: Path, endpoint: str) -> Path:
    """The peer's ``rover-hil.toml`` with Zenoh on, listening on ``endpoint`` (loopback, no scouting)."""
    text = peer_config.read_text(encoding="utf-8")
    zenoh = f'[zenoh]\nenabled = true\nlisten = ["{endpoint}"]\nconnect = []\nmulticast_scouting = false\n'
    if "[zenoh]\nenabled = false\n" not in text:
        raise SoakSetupError(f"{peer_config}: no `[zenoh] enabled = false` section to replace")
    # The map paths in the peer's config are relative to it.
    text = text.replace("[zenoh]\nenabled = false\n", zenoh).replace('"map/', f'"{peer_config.parent}/map/')
    out.write_text(text, encoding="utf-8")
    return out


def _ground_settings(endpoint: str) -> ZenohSettings:
    table = parse_toml(f'[zenoh]\nenabled = true\nlisten = []\nconnect = ["{endpoint}"]\n', "<soak>")
    return ZenohSettings.from_table(table.table("zenoh"))


def _rss_kb(pid: int) -> int | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except (FileNotFoundError, ProcessLookupError, ValueError):
        return None
    return None


def _tracebacks(log: Path) -> int:
    try:
        return log.read_text(encoding="utf-8", errors="replace").count("Traceback (most recent call last)")
    except FileNotFoundError:
        return 0


def _returncode(process: subprocess.Popen[bytes] | None) -> int | None:
    return None if process is None else process.returncode


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "rover_cli.main", *args]


def _stop(process: subprocess.Popen[bytes]) -> None:
    if process.poll() is not None:
        return
    process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout=30)
    except subprocess.TimeoutExpired:
        _log.error("soak: pid %d ignored SIGINT for 30 s; killing it", process.pid)
        process.kill()
        process.wait(timeout=10)


def _wait_for_file(path: Path, process: subprocess.Popen[bytes]) -> None:
    deadline = time.monotonic() + START_TIMEOUT_S
    while not (path.exists() and path.read_text(encoding="utf-8").strip()):
        if process.poll() is not None:
            raise SoakSetupError(f"the HIL peer exited ({process.returncode}) before writing {path}")
        if time.monotonic() > deadline:
            raise SoakSetupError(f"the HIL peer did not write {path} within {START_TIMEOUT_S:g} s")
        time.sleep(0.05)


def _wait_for_scenario_start(
    status_file: Path, peer: subprocess.Popen[bytes], rover: subprocess.Popen[bytes]
) -> float:
    """When the peer started its held scenario, on the rover's first wheel command (monotonic clock,
    s): what its status file says. A process that exits first, or a peer that never says, is a soak that
    cannot start (each log is in the soak's folder)."""
    deadline = time.monotonic() + ROVER_START_TIMEOUT_S + START_TIMEOUT_S
    while (started_ns := _scenario_started_ns(status_file)) is None:
        for name, process in (("rover run", rover), ("the HIL peer", peer)):
            if process.poll() is not None:
                raise SoakSetupError(
                    f"{name} exited ({process.returncode}) before the rover's first wheel command "
                    "started the scenario (see rover/rover.log and peer/peer.log)"
                )
        if time.monotonic() > deadline:
            raise SoakSetupError(f"the HIL peer did not say in {status_file} that its scenario started")
        time.sleep(0.05)
    return started_ns / 1e9


def _scenario_started_ns(status_file: Path) -> int | None:
    """The peer status's ``scenario_started_ns`` (None: not yet, or no whole status file yet)."""
    started = _peer_status(status_file).get("scenario_started_ns")
    return started if isinstance(started, int) else None


def _sleep_until(monotonic_s: float) -> None:
    remaining = monotonic_s - time.monotonic()
    if remaining > 0:
        time.sleep(remaining)


def _free_port() -> int:
    # Ask the OS for a free loopback port; the instant before Zenoh binds it is an accepted race.
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def _multicast_group(seed: int) -> str:
    # A group of its own per soak process, so a leftover peer can never talk to this rover.
    return f"239.75.{(os.getpid() >> 8) % 200 + 10}.{(os.getpid() + seed) % 250 + 1}"
