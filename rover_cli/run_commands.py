"""``rover run``: the onboard process on the companion computer (and for real-time HIL)."""

from __future__ import annotations

import argparse
import logging
import math
import os
import signal
import sys
import threading
import time
from pathlib import Path
from types import FrameType
from typing import Any

from rover_cli.arg_types import positive_seconds

_log = logging.getLogger(__name__)
DEFAULT_RUNS_DIR = Path("logs/trials")


def register(families: Any) -> None:
    run = families.add_parser("run", help="run the onboard stack in real time (the rover's process)")
    run.add_argument("--config", type=Path, required=True, help="rover config TOML (with a [map] table)")
    run.add_argument(
        "--goal", type=_point, default=None, help="drive to X,Y (local ENU metres; negative X: --goal=-5,3)"
    )
    run.add_argument(
        "--out", type=Path, default=None, help="recording directory (default: logs/trials/run-<t>)"
    )
    run.add_argument("--duration", type=positive_seconds, default=None, help="stop after this many seconds")
    run.add_argument("--no-telemetry", action="store_true", help="do not open Zenoh")
    run.set_defaults(handler=run_command)


def _point(text: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y in metres, got {text!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise argparse.ArgumentTypeError(f"expected X,Y as finite numbers of metres, got {text!r}")
    return x, y


def run_command(args: argparse.Namespace) -> int:
    from firmware_bridge.errors import BridgeError
    from logs.clock import MonotonicClock
    from logs.errors import TelemetrySetupError
    from logs.settings import ConfigError
    from navigator.config import load_rover_config
    from navigator.rover_process import RoverSetupError, check_runnable, run_rover

    try:
        config = load_rover_config(args.config)
        check_runnable(config)
    except (ConfigError, RoverSetupError) as err:
        _log.error("%s", err)
        return 2
    stop = threading.Event()
    _stop_on_signals(stop)
    out_dir = args.out or DEFAULT_RUNS_DIR / time.strftime("run-%Y%m%d-%H%M%S")
    duration_ns = None if args.duration is None else round(args.duration * 1e9)
    try:
        result = run_rover(
            config,
            MonotonicClock(),
            out_dir,
            stop=stop,
            goal=args.goal,
            duration_ns=duration_ns,
            telemetry=not args.no_telemetry,
            announce=_announce,
        )
    except (RoverSetupError, BridgeError, TelemetrySetupError) as err:
        # The config first, as in a config error: the settings that opened this link are in it.
        _log.error("%s: cannot start: %s", args.config, err)
        return 2
    finally:
        _ignore_signals_from_now_on()
    _announce(f"recording: {result.mcap_path}")
    _announce(f"timing: {result.timing.describe()}")
    return 0


def _announce(line: str) -> None:
    """A start-up milestone, on the console whatever the log level (an operator or journald reads it).

    Some are printed from inside the control loop (the start-up checks' events). A reader of stdout that
    went away (``rover run ... | head -2``, a log pipe closed) must not stop the rover there: the lines
    are on ``safety/events`` too, so from then on stdout goes to /dev/null, said once on stderr.
    """
    try:
        print(line, flush=True)
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        _log.warning("stdout's reader went away: its lines are no longer printed; the run goes on")


def _stop_on_signals(stop: threading.Event) -> None:
    """SIGINT / SIGTERM set ``stop``; one that arrives while stopping is noted and ignored (a second
    Ctrl-C, or systemd's SIGTERM after an operator's SIGINT, must not cut the shutdown short)."""

    def on_signal(signum: int, frame: FrameType | None) -> None:
        del frame
        name = signal.Signals(signum).name
        if stop.is_set():
            _log.warning("signal %s: already stopping; ignored", name)
            return
        _log.warning("signal %s: stopping (wheels to zero, recording closed)", name)
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)


def _ignore_signals_from_now_on() -> None:
    """Ignore SIGINT / SIGTERM once the run has closed everything.

    While the interpreter shuts down it puts the default handlers back before the last threads (Zenoh's)
    are gone: a second SIGINT 10 ms after the first then killed the process with status 130 after a
    clean stop. Nothing is left to protect by then, and a process that hangs here is still killed by
    systemd's SIGKILL after TimeoutStopSec.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
