"""``rover telemetry ...``: the ground station's side of the live Zenoh stream."""

from __future__ import annotations

import argparse
import math
import signal
import threading
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.live import Live
from rich.markup import escape
from rich.table import Table as RichTable

from logs.errors import LogsError
from rover_cli.arg_types import positive_seconds
from rover_cli.errors import print_error

# Long enough for a rover that publishes navigator/state at a thinned live rate (1-2 Hz) to show its
# next state; short enough that an operator is told quickly that an e-stop was not confirmed.
DEFAULT_CONFIRM_TIMEOUT_S = 5.0
# --no-wait only: let the put leave before the session closes (no component waits like this).
_FLUSH_S = 0.2


def register(families: Any) -> None:
    telemetry = families.add_parser("telemetry", help="watch, record and command a rover over Zenoh")
    commands = telemetry.add_subparsers(dest="command", required=True, metavar="SUBCOMMAND")

    def connection(parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--rover-id", default="rover1", help="names the key space rover/<id>/...")
        parser.add_argument(
            "--config", type=Path, default=None, help="rover config TOML with a [zenoh] table"
        )
        parser.add_argument(
            "--connect", action="append", default=[], help="endpoint of the rover or a router (tcp/HOST:PORT)"
        )

    watch = commands.add_parser(
        "watch",
        help="live table of pose, speed, modes, failsafes, goal, health and bus load",
        description="Exit status: 0 the rover was heard; 1 nothing was heard from it; 2 bad arguments "
        "or Zenoh setup.",
    )
    connection(watch)
    watch.add_argument(
        "--duration-s", type=positive_seconds, default=None, help="stop after this long (default: Ctrl-C)"
    )
    watch.set_defaults(handler=watch_command)

    record = commands.add_parser("record", help="record the live stream into an MCAP file")
    connection(record)
    record.add_argument("out", type=Path)
    record.add_argument(
        "--duration-s", type=positive_seconds, default=None, help="stop after this long (default: Ctrl-C)"
    )
    record.set_defaults(handler=record_command)

    send = commands.add_parser(
        "send",
        help="send a command (goal X Y | estop | resume) and confirm it from the rover's own streams",
        description="Exit status: 0 confirmed by the rover's safety/events or navigator/state; 1 not "
        "confirmed (nobody listening, refused, or no sign of the effect within the timeout); 2 bad "
        "arguments or Zenoh setup.",
    )
    connection(send)
    send.add_argument("kind", choices=("goal", "estop", "resume"))
    send.add_argument("xy", type=float, nargs="*", help="goal x y in ENU metres")
    send.add_argument(
        "--timeout-s",
        type=float,
        default=DEFAULT_CONFIRM_TIMEOUT_S,
        help=f"how long to wait for the rover to confirm (default {DEFAULT_CONFIRM_TIMEOUT_S:g} s)",
    )
    send.add_argument(
        "--no-wait",
        action="store_true",
        help="fire and forget: send and exit 0 without checking that any rover heard it (UNCONFIRMED)",
    )
    send.set_defaults(handler=send_command_line)


def _session(args: argparse.Namespace) -> Any:
    """The station's Zenoh session; ``TelemetrySetupError`` (exit 2) for a bad ``--rover-id``,
    ``--config`` or ``--connect``."""
    import dataclasses

    from logs.errors import TelemetrySetupError
    from logs.telemetry import ZenohSettings, endpoint_problem, key_prefix, open_session

    try:
        # Checked before anything opens: the subscription refused it only after the session was open
        # (and `record`'s file made), in a traceback.
        key_prefix(args.rover_id)
    except TelemetrySetupError as err:
        raise TelemetrySetupError(f"--rover-id: {err}") from err
    settings = ZenohSettings(enabled=True)
    if args.config is not None:
        settings = _station_config(args.config).zenoh
    if args.connect:
        for endpoint in args.connect:
            problem = endpoint_problem(endpoint)
            if problem is not None:
                raise TelemetrySetupError(f"--connect {endpoint!r}: {problem}")
        settings = dataclasses.replace(settings, connect=tuple(args.connect), listen=())
    try:
        return open_session(settings)
    except TelemetrySetupError as err:
        if not args.connect:
            raise
        raise TelemetrySetupError(f"--connect {' '.join(args.connect)}: {err}") from err


def _station_config(path: Path) -> Any:
    """The rover config ``--config`` names; ``TelemetrySetupError`` (exit 2) naming the file and key if it
    cannot be used (a missing or bad file had ended the command in a traceback)."""
    from logs.errors import TelemetrySetupError
    from logs.settings import ConfigError
    from navigator.config import load_rover_config

    try:
        return load_rover_config(path)
    except ConfigError as err:
        raise TelemetrySetupError(f"--config: {err}") from err


def _config_bitrate(args: argparse.Namespace) -> int | None:
    if args.config is None:
        return None
    return int(_station_config(args.config).can.bitrate)


def _wait(duration_s: float | None, tick: Any = None) -> None:
    """Until the duration has passed, Ctrl-C or SIGTERM (a station under systemd or docker is stopped that
    way: the recording must still be closed); ``tick()`` four times a second."""
    stop = threading.Event()
    deadline = None if duration_s is None else time.monotonic() + duration_s
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: stop.set())
    try:
        while not stop.is_set() and (deadline is None or time.monotonic() < deadline):
            if tick is not None:
                tick()
            stop.wait(0.25)
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)


def _say(console: Console, label: str, text: str) -> None:
    """``label`` (rich markup, e.g. a coloured verdict) then ``text`` as written: paths, ids, the rover's
    details and hints hold brackets (``[zenoh]``) that rich would read as markup and drop."""
    console.print(f"{label} {escape(text)}" if label else escape(text), highlight=False)


def _unreached_hint(args: argparse.Namespace) -> str:
    """What to check when the station reached no Zenoh peer or router at all."""
    if args.connect:
        return f"is the rover (or its router) up at --connect {' '.join(args.connect)}?"
    if args.config is not None:
        return f"does --config {args.config}'s [zenoh] connect name the rover (or its router)?"
    # Without either the station only listens on an OS-picked loopback port: nothing can find it.
    return (
        "no --connect given: name the rover's [zenoh] listen endpoint (or its router's), "
        "e.g. --connect tcp/HOST:7447"
    )


def watch_command(args: argparse.Namespace) -> int:
    from logs.clock import MonotonicClock
    from logs.telemetry import subscribe
    from logs.telemetry_station import LAST_HEARD, LiveView

    console = Console()
    try:
        session = _session(args)
    except LogsError as err:
        print_error(console, err)
        return 2
    # The rover reports its bus load itself (can/stats); the config's bitrate only serves an older rover.
    view = LiveView(MonotonicClock(), bitrate=_config_bitrate(args))
    subscription = subscribe(session, args.rover_id, view.update)
    started = time.monotonic()

    def table() -> RichTable:
        rendered = RichTable(title=f"rover {args.rover_id}: {view.samples} samples")
        rendered.add_column("what")
        rendered.add_column("value")
        stale = view.stale()
        for name, value in view.rows():
            # Rows are plain text (a rover's detail may hold brackets rich would read as markup).
            rendered.add_row(name, value, style="bold red" if name == LAST_HEARD and stale else None)
        return rendered

    nothing = ""
    try:
        with Live(table(), console=console, refresh_per_second=4) as live:
            _wait(args.duration_s, lambda: live.update(table()))
        if view.samples == 0:
            nothing = _heard_nothing(args, session, time.monotonic() - started)
    finally:
        subscription.close()
        session.close()
    if not nothing:
        return 0
    _say(console, "[red]heard nothing:[/red]", nothing)
    return 1


def _heard_nothing(args: argparse.Namespace, session: Any, waited_s: float) -> str:
    """Why a station heard no message from the rover: whom it reached, and what to check."""
    info = session.info
    peers, routers = len(info.peers_zid()), len(info.routers_zid())
    reached = (
        "no Zenoh peer or router"
        if peers + routers == 0
        else f"{peers} Zenoh peer(s) and {routers} router(s), none publishing rover/{args.rover_id}/**"
    )
    hint = f"is {args.rover_id!r} the rover's id (--rover-id)?" if peers + routers else _unreached_hint(args)
    return (
        f"no message from rover {args.rover_id} in {waited_s:.1f} s; this station is connected to {reached}"
        + (f"; {hint}" if hint else "")
    )


def record_command(args: argparse.Namespace) -> int:
    from logs.recorder import McapRecorder
    from logs.telemetry_station import StreamRecorder

    console = Console()
    if args.out.is_file():
        # The recorder opens its file for writing: an earlier recording there would be emptied.
        print_error(
            console,
            f"{args.out} already exists (an earlier recording; it is left as it is): "
            "give another file name, or move that file away",
        )
        return 2
    try:
        session = _session(args)
        recorder = McapRecorder(args.out, exclusive=True)
    except LogsError as err:
        print_error(console, err)
        return 2
    stream = StreamRecorder(session, args.rover_id, recorder)
    started = time.monotonic()
    nothing = ""
    try:
        with console.status(f"recording rover/{args.rover_id}/** into {args.out} ..."):
            _wait(args.duration_s)
        if stream.recorded == 0:
            nothing = _heard_nothing(args, session, time.monotonic() - started)
    finally:
        stream.close()
        recorder.close()
        session.close()
    _say(
        console,
        "",
        f"{args.out}: {stream.recorded} messages on {len(stream.topics)} topics; "
        f"{stream.rejected} samples rejected, {stream.failed} not recorded",
    )
    if nothing:  # as watch: a script notices a recording of nothing
        _say(console, "[red]heard nothing:[/red]", nothing)
        return 1
    return 0


def send_command_line(args: argparse.Namespace) -> int:
    from logs.clock import MonotonicClock
    from logs.command_confirm import send_confirmed
    from logs.command_watch import Verdict
    from logs.commands import send_command

    console = Console()
    if (args.kind == "goal") != (len(args.xy) == 2) or (args.kind != "goal" and args.xy):
        console.print(
            "[red]error:[/red] goal takes exactly two numbers (x y, metres); estop/resume take none"
        )
        return 2
    if not all(math.isfinite(v) for v in args.xy):
        # argparse's float takes 'nan' and 'inf'; the rover would only count such a goal as rejected.
        given = " ".join(f"{v:g}" for v in args.xy)
        console.print(f"[red]error:[/red] goal x y must be finite numbers (metres), got {given}")
        return 2
    if not args.timeout_s > 0:
        console.print(f"[red]error:[/red] --timeout-s must be > 0, got {args.timeout_s:g}")
        return 2
    try:
        session = _session(args)
    except LogsError as err:
        print_error(console, err)
        return 2
    x, y = [*args.xy, None, None][:2]
    what = f"{args.kind} {x:g} {y:g}" if args.kind == "goal" else args.kind
    try:
        if args.no_wait:
            send_command(session, args.rover_id, args.kind, x, y)
            time.sleep(_FLUSH_S)
        else:
            with console.status(f"sending {what} to rover {args.rover_id}, waiting for it to confirm ..."):
                outcome = send_confirmed(
                    session, args.rover_id, args.kind, x, y, timeout_s=args.timeout_s, clock=MonotonicClock()
                )
    except LogsError as err:
        print_error(console, err)
        return 2
    finally:
        session.close()
    if args.no_wait:
        console.print(
            f"sent {escape(what)} to rover {escape(args.rover_id)} [yellow]UNCONFIRMED[/yellow] "
            "(--no-wait: nothing checked that a rover heard it)",
            highlight=False,
        )
        return 0
    if outcome.confirmed:
        _say(console, "[green]confirmed:[/green]", f"rover {args.rover_id} {what}: {outcome.detail}")
        return 0
    hint = ""
    if outcome.verdict is Verdict.NO_LISTENER and outcome.connections == 0:
        hint = f"; {_unreached_hint(args)}"
    elif outcome.verdict is Verdict.NO_LISTENER and outcome.connections:
        hint = f"; is {args.rover_id!r} the rover's id (--rover-id)?"
    _say(console, "[red]NOT confirmed:[/red]", f"rover {args.rover_id} {what}: {outcome.detail}{hint}")
    return 1
