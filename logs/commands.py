"""Commands to the rover over Zenoh: a new goal, an emergency stop, resume after an e-stop.

Keys: ``rover/<rover_id>/cmd/goal`` (payload ``{"x": <m>, "y": <m>}``, local ENU), ``.../cmd/estop`` and
``.../cmd/resume`` (payload ``{}``; any JSON object is accepted, extra fields are ignored). A command that
does not decode is counted in ``rejected`` and logged (the first few), never raised: a ground station's
bad packet must not stop the rover loop.

The onboard loop reads commands with ``CommandSource.poll()``: non-blocking, thread-safe, each command
returned once, in arrival order. ``received_ns`` is the receiver's clock at arrival, so a lockstep trial
stays on its simulated time.
"""

from __future__ import annotations

import json
import logging
import math
import threading
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import zenoh

from logs.clock import Clock
from logs.errors import TelemetryError, TelemetrySetupError
from logs.json_text import loads_json
from logs.telemetry import key_prefix, undeclare_quietly
from logs.topics import stamp, stamp_ns

logger = logging.getLogger(__name__)

CommandKind = Literal["goal", "estop", "resume"]
COMMAND_KINDS: tuple[CommandKind, ...] = ("goal", "estop", "resume")
COMMAND_SEGMENT = "cmd"
_MAX_WARNINGS = 10
# A goal is local ENU metres; anything beyond this is a unit mistake (degrees, millimetres), not a goal.
MAX_GOAL_COORDINATE_M = 1.0e6


# Where a command came from: the ground station over Zenoh (read inside a tick, and the ground-link
# failsafe's sign of contact), or `rover run --goal` (given once, before the loop).
CommandOrigin = Literal["zenoh", "command line"]
COMMAND_ORIGINS: tuple[CommandOrigin, ...] = ("zenoh", "command line")


@dataclass(frozen=True)
class RoverCommand:
    """One accepted command. ``x``/``y`` (ENU metres) only for ``goal``; ``received_ns`` from the clock."""

    kind: CommandKind
    received_ns: int
    x: float | None = None
    y: float | None = None
    origin: CommandOrigin = "zenoh"


class CommandSource(Protocol):
    # When the ground station was last heard from (any sample, even a malformed one), on the rover's
    # clock; None before the first. The ground-link failsafe watches it.
    last_contact_ns: int | None

    def poll(self) -> list[RoverCommand]:
        """Commands received since the last poll, oldest first; never blocks."""
        ...


def command_key(rover_id: str, kind: CommandKind) -> str:
    return f"{key_prefix(rover_id)}/{COMMAND_SEGMENT}/{kind}"


def parse_command(kind: str, payload: bytes, received_ns: int) -> RoverCommand:
    """A command from its key's last segment and JSON payload; ``ValueError`` naming what is wrong."""
    if kind not in COMMAND_KINDS:
        raise ValueError(f"unknown command {kind!r}; expected one of {', '.join(COMMAND_KINDS)}")
    try:
        body = loads_json(payload)
    except ValueError as err:
        raise ValueError(f"{kind} payload is not JSON: {err}") from err
    if not isinstance(body, dict):
        raise ValueError(f"{kind} payload is a JSON {type(body).__name__}, not an object")
    return _command_from_body(kind, body, received_ns)


def command_record(t_ns: int, command: RoverCommand) -> dict[str, object]:
    """The ``ground/commands`` message of a command the stack read at ``t_ns``."""
    return {
        "timestamp": stamp(t_ns),
        "kind": command.kind,
        "x": command.x,
        "y": command.y,
        "received": stamp(command.received_ns),
        "origin": command.origin,
    }


def command_from_record(record: dict[str, Any]) -> RoverCommand:
    """The command a ``ground/commands`` message holds; ``ValueError`` naming what is wrong, as
    ``parse_command`` for a payload."""
    kind = record.get("kind")
    if not isinstance(kind, str) or kind not in COMMAND_KINDS:
        raise ValueError(f"unknown command {kind!r}; expected one of {', '.join(COMMAND_KINDS)}")
    received = record.get("received")
    try:
        if not isinstance(received, dict):
            raise TypeError(type(received).__name__)
        received_ns = stamp_ns(received)
    except (KeyError, TypeError, ValueError, OverflowError) as err:  # Overflow: an infinite float
        raise ValueError(f"{kind} record's received time is {received!r}: {err!r}") from err
    if received_ns < 0:
        raise ValueError(f"{kind} record's received time {received_ns} ns is negative")
    origin = record.get("origin", "zenoh")  # recordings made before the field: Zenoh's alone
    if origin not in COMMAND_ORIGINS:
        raise ValueError(f"{kind} record's origin {origin!r} is none of {', '.join(COMMAND_ORIGINS)}")
    return _command_from_body(kind, record, received_ns, origin)


def _command_from_body(
    kind: CommandKind, body: dict[str, Any], received_ns: int, origin: CommandOrigin = "zenoh"
) -> RoverCommand:
    if kind != "goal":
        return RoverCommand(kind, received_ns, origin=origin)
    coordinates = []
    for axis in ("x", "y"):
        value = body.get(axis)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"goal needs a number {axis!r} in metres, got {value!r}")
        # The bound first: an integer of hundreds of digits is too large for math.isfinite's float.
        if abs(value) > MAX_GOAL_COORDINATE_M or not math.isfinite(value):
            raise ValueError(f"goal {axis}={value!r} is not a finite ENU coordinate within 1000 km")
        coordinates.append(float(value))
    return RoverCommand("goal", received_ns, coordinates[0], coordinates[1], origin)


class ZenohCommandReceiver:
    """``CommandSource`` subscribed to ``rover/<rover_id>/cmd/*``; the session is the caller's."""

    def __init__(self, session: zenoh.Session, rover_id: str, clock: Clock) -> None:
        self._prefix = f"{key_prefix(rover_id)}/{COMMAND_SEGMENT}/"
        self._clock = clock
        self._lock = threading.Lock()  # zenoh delivers on its own threads; poll() runs on the rover loop
        self._pending: list[RoverCommand] = []
        self.accepted = 0
        self.rejected = 0
        self.last_contact_ns: int | None = None
        self._closed = False
        try:
            self._subscriber = session.declare_subscriber(self._prefix + "*", self._on_sample)
        except zenoh.ZError as err:
            raise TelemetrySetupError(f"cannot subscribe to {self._prefix}*: {err}") from err

    def _on_sample(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        kind = key[len(self._prefix) :] if key.startswith(self._prefix) else key
        received_ns = self._clock.now_ns()
        self.last_contact_ns = received_ns
        try:
            command = parse_command(kind, sample.payload.to_bytes(), received_ns)
        except ValueError as err:
            with self._lock:
                self.rejected += 1
                rejected = self.rejected
            if rejected <= _MAX_WARNINGS:
                logger.warning("command on %s rejected: %s", key, err)
            return
        with self._lock:
            self._pending.append(command)
            self.accepted += 1
        logger.info("command accepted: %s", command)

    def poll(self) -> list[RoverCommand]:
        with self._lock:
            commands, self._pending = self._pending, []
        return commands

    def close(self) -> None:
        """Stop receiving. Safe to call twice."""
        if self._closed:
            return
        self._closed = True
        undeclare_quietly(self._subscriber, self._prefix)


def command_payload(kind: CommandKind, x: float | None = None, y: float | None = None) -> bytes:
    """The JSON a command travels as; ``TelemetryError`` for a goal without both coordinates."""
    if kind == "goal":
        if x is None or y is None:
            raise TelemetryError("a goal command needs x and y (ENU metres)")
        return json.dumps({"x": float(x), "y": float(y)}).encode()
    return b"{}"


def send_command(
    session: zenoh.Session, rover_id: str, kind: CommandKind, x: float | None = None, y: float | None = None
) -> None:
    """Publish one command, fire and forget (nothing says whether a rover heard it; for that, see
    ``logs.command_confirm.send_confirmed``). ``TelemetryError`` if the put fails."""
    payload = command_payload(kind, x, y)
    try:
        session.put(command_key(rover_id, kind), payload, encoding=zenoh.Encoding.APPLICATION_JSON)
    except zenoh.ZError as err:
        raise TelemetryError(f"cannot send {kind} to rover {rover_id!r}: {err}") from err
