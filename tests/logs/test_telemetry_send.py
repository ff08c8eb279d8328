"""``rover telemetry send`` over real loopback Zenoh: confirmed by a rover that answers, refused, or not.

The fake rover is a listening session with the real ``ZenohCommandReceiver`` and ``ZenohTelemetry``; a
thread plays the onboard loop: every tick it reads commands and publishes ``navigator/state`` (and the
``safety/events`` entries ``navigator.onboard`` would). Multicast scouting off, OS-chosen ports.
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import zenoh

from logs import topics
from logs.clock import MonotonicClock
from logs.command_confirm import send_confirmed
from logs.command_watch import Verdict
from logs.commands import ZenohCommandReceiver
from logs.errors import TelemetryError, TelemetrySetupError
from logs.telemetry import ZenohSettings, ZenohTelemetry, open_session, zenoh_config
from rover_cli.main import main

pytestmark = pytest.mark.realtime  # a rover must answer within the command's timeout (0.2-1 s)

TICK_S = 0.02
MAP_M = 20.0
SHORT_TIMEOUT_S = 1.0


def _free_loopback_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


class FakeRover:
    """Acts on commands the way the onboard loop does, or (``answers=False``) hears them and says nothing."""

    def __init__(
        self,
        session: zenoh.Session,
        rover_id: str,
        *,
        answers: bool,
        max_goal_m: float,
        map_m: float = MAP_M,
        plans: bool = True,
    ) -> None:
        """``max_goal_m``: the geofence; ``map_m``: the map (a goal off it is taken, then found unreachable);
        ``plans=False``: takes goals but never finishes planning."""
        self.receiver = ZenohCommandReceiver(session, rover_id, MonotonicClock())
        self._telemetry = ZenohTelemetry(session, rover_id)
        self._answers = answers
        self._max_goal_m = max_goal_m
        self._map_m = map_m
        self._plans = plans
        self.estopped = False
        self.goal: tuple[float, float] | None = None
        self.mode = "IDLE"
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="fake-rover", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(TICK_S):
            for command in self.receiver.poll():
                if command.kind == "estop":
                    self.estopped = True
                    self._publish(
                        topics.SAFETY_EVENTS, _event("failsafe.estop", "emergency stop from ground")
                    )
                elif command.kind == "resume":
                    self.estopped = False
                    self._publish(topics.SAFETY_EVENTS, _event("cleared.estop", "resume from ground station"))
                elif command.x is not None and command.y is not None:
                    if max(abs(command.x), abs(command.y)) > self._max_goal_m:
                        detail = f"goal ({command.x:.2f}, {command.y:.2f}) is outside the geofence"
                        self._publish(topics.SAFETY_EVENTS, _event("goal_rejected", detail))
                    else:
                        self.goal = (command.x, command.y)
                        self.mode = "PLANNING"  # the state of this tick; the plan's outcome comes next
                        detail = f"new goal ({command.x:.2f}, {command.y:.2f})"
                        self._publish(topics.SAFETY_EVENTS, _event("goal", detail))
            goal = self.goal or (float("nan"), float("nan"))
            reason = "safety estop" if self.estopped else "cruise"
            self._publish(
                topics.NAVIGATOR_STATE,
                {
                    "mode": self.mode,
                    "goal": {"x": goal[0], "y": goal[1]},
                    "speed_limit_mps": 0.0 if self.estopped else 1.0,
                    "speed_limit_reason": reason,
                    "safety_mode": "ESTOP" if self.estopped else "DRIVING",
                    "failsafes": ["estop"] if self.estopped else [],
                },
            )
            if self.mode == "PLANNING" and self._plans:
                self.mode = "DRIVING" if max(abs(goal[0]), abs(goal[1])) <= self._map_m else "NO_PATH"
                if self.mode == "NO_PATH":
                    detail = f"cannot plan: goal position is not on the map: point ({goal[0]:.3f}, ...)"
                    self._publish(topics.SAFETY_EVENTS, _event("guidance.no_path", detail))

    def _publish(self, topic: str, message: dict[str, Any]) -> None:
        if self._answers:
            self._telemetry.publish(topic, time.monotonic_ns(), message)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._telemetry.close()
        self.receiver.close()


def _event(kind: str, detail: str) -> dict[str, Any]:
    return {"kind": kind, "severity": "info", "detail": detail}


@pytest.fixture
def endpoint() -> str:
    return f"tcp/127.0.0.1:{_free_loopback_port()}"


def _rover(
    endpoint: str, *, answers: bool = True, max_goal_m: float = 100.0, plans: bool = True
) -> Iterator[FakeRover]:
    session = open_session(ZenohSettings(enabled=True, listen=(endpoint,)))
    rover = FakeRover(session, "r1", answers=answers, max_goal_m=max_goal_m, plans=plans)
    try:
        yield rover
    finally:
        rover.close()
        session.close()


@pytest.fixture
def rover(endpoint: str) -> Iterator[FakeRover]:
    yield from _rover(endpoint)


@pytest.fixture
def deaf_rover(endpoint: str) -> Iterator[FakeRover]:
    yield from _rover(endpoint, answers=False)


def _send(capsys: pytest.CaptureFixture[str], endpoint: str, *words: str) -> tuple[int, str, float]:
    """Run ``rover telemetry send`` in-process: (exit code, output on one line, seconds taken)."""
    started = time.monotonic()
    code = main(["telemetry", "send", *words, "--rover-id", "r1", "--connect", endpoint])
    taken = time.monotonic() - started
    return code, " ".join(capsys.readouterr().out.split()), taken


def test_estop_goal_resume_confirmed_by_a_rover_that_answers(
    rover: FakeRover, endpoint: str, capsys: pytest.CaptureFixture[str]
) -> None:
    # The event and the state come from two publishers and reach the station on separate threads, so
    # either may confirm first; both mean the rover acted on the command.
    code, out, _ = _send(capsys, endpoint, "estop", "--timeout-s", "5")
    assert code == 0, out
    assert out.startswith("confirmed: rover r1 estop:"), out
    assert "failsafe.estop" in out or "'safety estop'" in out, out
    assert rover.estopped

    code, out, _ = _send(capsys, endpoint, "goal", "3.5", "-2", "--timeout-s", "5")
    assert code == 0, out
    assert out.startswith("confirmed: rover r1 goal 3.5 -2: navigator/state:"), out
    assert "goal (3.50, -2.00)" in out, out

    code, out, _ = _send(capsys, endpoint, "resume", "--timeout-s", "5")
    assert code == 0, out
    assert out.startswith("confirmed: rover r1 resume:"), out
    assert "cleared.estop" in out or "'cruise'" in out, out
    assert not rover.estopped


def test_no_rover_exits_non_zero_within_the_timeout(
    endpoint: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, taken = _send(capsys, endpoint, "estop", "--timeout-s", str(SHORT_TIMEOUT_S))
    assert code == 1, out
    assert "NOT confirmed" in out and "no rover is listening" in out and "rover/r1/cmd/estop" in out, out
    assert f"--connect {endpoint}" in out
    assert SHORT_TIMEOUT_S * 0.9 <= taken < SHORT_TIMEOUT_S + 1.5


def test_a_wrong_rover_id_is_told_apart_from_an_unreachable_rover(
    rover: FakeRover, endpoint: str, capsys: pytest.CaptureFixture[str]
) -> None:
    timeout = str(SHORT_TIMEOUT_S)
    code = main(
        ["telemetry", "send", "estop", "--rover-id", "r2", "--connect", endpoint, "--timeout-s", timeout]
    )
    out = " ".join(capsys.readouterr().out.split())
    assert code == 1, out
    assert "connected to 1 Zenoh peer(s) and 0 router(s), none subscribed" in out, out
    assert "is 'r2' the rover's id (--rover-id)?" in out, out
    assert not rover.estopped


def test_a_rover_that_hears_but_does_not_answer_is_not_confirmed(
    deaf_rover: FakeRover, endpoint: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, taken = _send(capsys, endpoint, "goal", "1", "2", "--timeout-s", str(SHORT_TIMEOUT_S))
    assert code == 1, out
    assert "reached a subscriber" in out and "navigator/state's goal becoming (1.00, 2.00)" in out, out
    assert "heard nothing on safety/events or navigator/state" in out, out
    assert deaf_rover.goal == (1.0, 2.0)  # it did arrive: only the confirmation is missing
    assert taken < SHORT_TIMEOUT_S + 1.5


def test_a_refused_goal_exits_non_zero_with_the_rovers_reason(
    endpoint: str, capsys: pytest.CaptureFixture[str]
) -> None:
    for _ in _rover(endpoint, max_goal_m=10.0):
        code, out, _ = _send(capsys, endpoint, "goal", "30", "3", "--timeout-s", "5")
        assert code == 1, out
        assert "NOT confirmed" in out and "refused the goal" in out and "geofence" in out, out


def test_a_goal_off_the_map_is_taken_then_refused_with_the_planners_reason(
    rover: FakeRover, endpoint: str, capsys: pytest.CaptureFixture[str]
) -> None:
    # Inside the geofence, so the rover takes it; the planner then proves it unreachable. Acceptance is
    # not success: the operator must hear "no path" and why, not "confirmed ... PLANNING".
    code, out, _ = _send(capsys, endpoint, "goal", "30", "3", "--timeout-s", "5")
    assert code == 1, out
    assert out.startswith(
        "NOT confirmed: rover r1 goal 30 3: the rover accepted the goal but cannot reach"
    ), out
    assert "guidance.no_path" in out and "goal position is not on the map" in out, out
    assert rover.goal == (30.0, 3.0) and rover.mode == "NO_PATH"

    code, out, _ = _send(capsys, endpoint, "goal", "3.5", "-2", "--timeout-s", "5")
    assert code == 0, out
    assert "mode DRIVING, safety DRIVING, goal (3.50, -2.00)" in out, out


def test_a_goal_whose_plan_never_comes_is_not_confirmed_and_says_it_was_accepted(
    endpoint: str, capsys: pytest.CaptureFixture[str]
) -> None:
    for _ in _rover(endpoint, plans=False):
        code, out, taken = _send(capsys, endpoint, "goal", "1", "2", "--timeout-s", str(SHORT_TIMEOUT_S))
        assert code == 1, out
        assert "the rover accepted the goal (1.00, 2.00) but showed no plan outcome" in out, out
        assert "the last navigator/state: mode PLANNING, safety DRIVING, goal (1.00, 2.00)" in out, out
        assert taken < SHORT_TIMEOUT_S + 1.5


def _watch(capsys: pytest.CaptureFixture[str], endpoint: str, duration_s: float) -> tuple[int, str]:
    code = main(
        ["telemetry", "watch", "--rover-id", "r1", "--connect", endpoint, "--duration-s", str(duration_s)]
    )
    return code, " ".join(capsys.readouterr().out.split())


def test_watch_with_no_rover_says_it_heard_nothing_and_exits_non_zero(
    endpoint: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out = _watch(capsys, endpoint, SHORT_TIMEOUT_S)
    assert code == 1, out
    assert "heard nothing: no message from rover r1" in out, out
    assert "connected to no Zenoh peer or router" in out and f"--connect {endpoint}" in out, out


def test_watch_shows_a_rover_it_hears_and_exits_zero(
    rover: FakeRover, endpoint: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out = _watch(capsys, endpoint, SHORT_TIMEOUT_S)
    assert code == 0, out
    assert "heard nothing" not in out and "last heard" in out, out
    assert "mode (guidance)" in out and "mode (safety)" in out and "failsafes active" in out, out


def test_no_wait_is_fire_and_forget_and_says_so(endpoint: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _send(capsys, endpoint, "estop", "--no-wait")
    assert code == 0
    assert "sent estop to rover r1 UNCONFIRMED" in out and "nothing checked" in out, out


def test_send_confirmed_refuses_a_non_positive_timeout(rover: FakeRover, endpoint: str) -> None:
    session = open_session(ZenohSettings(enabled=True, listen=(), connect=(endpoint,)))
    try:
        with pytest.raises(TelemetryError, match="timeout"):
            send_confirmed(session, "r1", "estop", timeout_s=0.0, clock=MonotonicClock())
        outcome = send_confirmed(session, "r1", "estop", timeout_s=5.0, clock=MonotonicClock())
        assert outcome.verdict is Verdict.CONFIRMED
    finally:
        session.close()


@pytest.mark.parametrize("bad", ["nonsense", "tcp/"])
def test_a_bad_connect_value_is_named_not_the_shipped_config(
    bad: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["telemetry", "send", "estop", "--connect", bad])
    out = " ".join(capsys.readouterr().out.split())
    assert code == 2
    assert f"--connect {bad!r}" in out and "shipped" not in out, out


def test_zenoh_config_names_the_endpoint_zenoh_refuses() -> None:
    # Past our own '<protocol>/<address>' check, zenoh's refusal still names the value, not the file.
    with pytest.raises(TelemetrySetupError) as caught:
        zenoh_config(ZenohSettings(enabled=True, listen=("tcp/127.0.0.1:0?x",), connect=("nonsense",)))
    message = str(caught.value)
    assert "connect endpoints ['nonsense']" in message and "shipped" not in message
    assert ".rs:" not in message  # zenoh's Rust source location is noise to an operator


def test_record_says_it_heard_nothing_and_exits_non_zero_as_watch_does(
    endpoint: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "station.mcap"
    args = ["telemetry", "record", str(out), "--rover-id", "r1", "--connect", endpoint]
    assert main([*args, "--duration-s", str(SHORT_TIMEOUT_S)]) == 1
    printed = " ".join(capsys.readouterr().out.split())
    assert "0 messages on 0 topics" in printed and "heard nothing: no message from rover r1" in printed
    assert out.is_file()  # the (empty) recording is still closed properly


def test_record_of_a_rover_it_hears_exits_zero(
    rover: FakeRover, endpoint: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "station.mcap"
    args = ["telemetry", "record", str(out), "--rover-id", "r1", "--connect", endpoint]
    # Long enough for the session to connect and a sample to come on a loaded 2-core host.
    assert main([*args, "--duration-s", "4"]) == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert "heard nothing" not in printed and "0 messages" not in printed, printed
