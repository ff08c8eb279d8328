"""``rover run``: the onboard process on the companion computer (and for real-time HIL)."""

from __future__ import annotations

import argparse
import logging
import signal
import threading
import time
from pathlib import Path
from types import FrameType
from typing import Any

_log = logging.getLogger(__name__)
DEFAULT_RUNS_DIR = Path("logs/trials")


def register(families: Any) -> None:
    run = families.add_parser("run", help="run the onboard stack in real time (the rover's process)")
    run.add_argument("--config", type=Path, required=True, help="rover config TOML (with a [map] table)")
    run.add_argument("--goal", type=_point, default=None, help="drive to X,Y (local ENU metres)")
    run.add_argument(
        "--out", type=Path, default=None, help="recording directory (default: logs/trials/run-<t>)"
    )
    run.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    run.add_argument("--no-telemetry", action="store_true", help="do not open Zenoh")
    run.set_defaults(handler=run_command)


def _point(text: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y in metres, got {text!r}") from None
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

    def on_signal(signum: int, frame: FrameType | None) -> None:
        del frame
        _log.warning("signal %s: stopping (wheels to zero, recording closed)", signal.Signals(signum).name)
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
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
        )
    except (RoverSetupError, BridgeError, TelemetrySetupError) as err:
        _log.error("cannot start: %s", err)
        return 2
    print(f"recording: {result.mcap_path}")
    print(f"timing: {result.timing.describe()}")
    return 0
