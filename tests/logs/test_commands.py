"""Commands over Zenoh: parsing, and goal / e-stop / resume crossing loopback to a receiver."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Iterator

import pytest
import zenoh

from logs.clock import SimClock
from logs.commands import RoverCommand, ZenohCommandReceiver, command_key, parse_command, send_command
from logs.errors import TelemetryError, TelemetrySetupError
from logs.telemetry import ZenohSettings, open_session

WAIT_S = 10.0


def _free_loopback_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_parse_goal_estop_resume() -> None:
    assert parse_command("goal", b'{"x": 3, "y": -2.5}', 7) == RoverCommand("goal", 7, 3.0, -2.5)
    assert parse_command("estop", b"{}", 8) == RoverCommand("estop", 8)
    assert parse_command("resume", b'{"why": "clear"}', 9) == RoverCommand("resume", 9)
    assert command_key("r1", "estop") == "rover/r1/cmd/estop"


@pytest.mark.parametrize(
    ("kind", "payload", "match"),
    [
        ("goal", b'{"x": 1}', "'y'"),
        ("goal", b'{"x": "1", "y": 2}', "'x'"),
        ("goal", b'{"x": true, "y": 2}', "'x'"),
        ("goal", b'{"x": 1e300, "y": 2}', "finite"),
        ("goal", b'{"x": ' + b"9" * 400 + b', "y": 2}', "finite"),  # too large for a float: no OverflowError
        ("goal", b'{"x": NaN, "y": 2}', "finite"),
        ("goal", b"[" * 100_000 + b"]" * 100_000, "nested too deep"),  # no RecursionError
        ("goal", b"not json", "not JSON"),
        ("estop", b"[1]", "not an object"),
        ("launch", b"{}", "unknown command"),
    ],
)
def test_parse_rejects_with_a_reason(kind: str, payload: bytes, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        parse_command(kind, payload, 0)


def test_bad_rover_id_is_a_setup_error() -> None:
    with pytest.raises(TelemetrySetupError, match="rover_id"):
        ZenohCommandReceiver(None, "a/b", SimClock())  # type: ignore[arg-type]


@pytest.fixture
def sessions() -> Iterator[tuple[zenoh.Session, zenoh.Session]]:
    endpoint = f"tcp/127.0.0.1:{_free_loopback_port()}"
    rover = open_session(ZenohSettings(enabled=True, listen=(endpoint,)))
    try:
        station = open_session(ZenohSettings(enabled=True, listen=(), connect=(endpoint,)))
    except BaseException:
        rover.close()
        raise
    try:
        yield rover, station
    finally:
        station.close()
        rover.close()


def _until(predicate: Callable[[], bool], action: Callable[[], None] | None = None) -> bool:
    """Repeat ``action`` until ``predicate`` holds (bounded): discovery over loopback takes a moment."""
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        if action is not None:
            action()
        if predicate():
            return True
        threading.Event().wait(0.02)
    return False


def test_commands_cross_loopback_in_order(sessions: tuple[zenoh.Session, zenoh.Session]) -> None:
    rover, station = sessions
    clock = SimClock()
    clock.advance(123)
    receiver = ZenohCommandReceiver(rover, "r7", clock)
    seen: list[RoverCommand] = []
    try:
        # Probe with resumes until the route is up, then send the real sequence.
        def probe_arrived() -> bool:
            seen.extend(receiver.poll())
            return bool(seen)

        assert _until(probe_arrived, lambda: send_command(station, "r7", "resume"))
        assert all(command.kind == "resume" for command in seen)
        send_command(station, "r7", "goal", 4.0, 5.5)
        send_command(station, "r7", "estop")
        station.put("rover/r7/cmd/goal", b'{"x": "north"}')  # malformed: counted, not raised
        station.put("rover/r7/cmd/estop", b"garbage")
        send_command(station, "r7", "resume")
        got: list[RoverCommand] = []

        def sequence_arrived() -> bool:
            got.extend(receiver.poll())
            kinds = [command.kind for command in got]
            return "goal" in kinds and "resume" in kinds[kinds.index("goal") :] and receiver.rejected >= 2

        assert _until(sequence_arrived)
        # Probes may still trickle in before the real sequence: compare from the goal on.
        kinds = [command.kind for command in got]
        tail = got[kinds.index("goal") :]
        assert tail == [
            RoverCommand("goal", 123, 4.0, 5.5),
            RoverCommand("estop", 123),
            RoverCommand("resume", 123),
        ]
        assert receiver.rejected == 2
        assert receiver.poll() == []  # each command is handed out once
    finally:
        receiver.close()
        receiver.close()


def test_goal_without_coordinates_is_refused_by_the_sender(
    sessions: tuple[zenoh.Session, zenoh.Session],
) -> None:
    with pytest.raises(TelemetryError, match="x and y"):
        send_command(sessions[1], "r7", "goal", 1.0, None)


def test_any_sample_counts_as_ground_contact(sessions: tuple[zenoh.Session, zenoh.Session]) -> None:
    rover, station = sessions
    clock = SimClock(start_ns=5_000)
    receiver = ZenohCommandReceiver(rover, "r1", clock)
    try:
        assert receiver.last_contact_ns is None
        # Even a malformed goal shows the station is there: the ground-link failsafe watches contact.
        assert _until(
            lambda: receiver.last_contact_ns == 5_000,
            lambda: station.put(command_key("r1", "goal"), b"not json"),
        )
        assert receiver.poll() == []
    finally:
        receiver.close()
