"""``rover hil peer --start-on-command``: the scenario is held until the rover's first wheel command.

``run_peer`` runs in-process on a virtual clock that moves only by the peer's waits; a rover on the other
end of the lockstep bus (the real ``CanLink``) takes its turn every 20 ms, and sends wheel commands from
``commands_from_s`` on, as ``rover run`` would once it came up. A fault at T must begin T after that
first command, not T after the peer's start; a rover that never commands is given up on, and the peer
says so.
"""

from __future__ import annotations

import io
import json
import math
import signal
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink2

import hil.peer
from firmware_bridge.can_link import CanLink
from firmware_bridge.mavlink_transport import PipeEnd
from firmware_bridge.vesc import VescCodec
from hil.lockstep import lockstep_wires
from hil.peer import PeerResult
from hil.peer_stalls import PeerStalls
from hil.peer_start import ON_FIRST_COMMAND, ON_PEER_START, ScenarioStart
from hil.realtime_metrics import realtime_metrics
from hil.world import SimWorld
from logs import topics
from logs.clock import NS_PER_S, SimClock, to_ns
from logs.reader import read_messages, read_metadata
from logs.recorder import McapRecorder
from logs.settings import parse_toml
from logs.sink import MemorySink
from navigator.config import RoverConfig, rover_config_from_table
from navigator.runtime import TimingStats
from rover_cli.main import main
from tests.hil.test_realtime_metrics_epoch import WORLD_START_NS, _write_rover, _write_truth
from tests.hil.test_world_epoch import CART  # waits 600 s at (2, 7), then 1 m/s down x = 2
from tests.hil.world_harness import run_peer_on_test_clock, scenario_with

MS = 1_000_000
T0_NS = 1_000 * NS_PER_S  # a monotonic clock's epoch is arbitrary; not zero
ROVER_PERIOD_NS = 20 * MS
PHYSICS_NS = 10 * MS
FAULT_AT_S = 1.0
GPS_OFF = f'[[faults]]\ntarget = "gps"\nkind = "off"\nstart_s = {FAULT_AT_S}\nduration_s = 0.5\n'
NEVER = math.inf


@dataclass
class Rover:
    """The rover's side: from ``commands_from_ns`` on, a round of zero wheel commands (what a rover not
    yet ready sends) every turn. Before that it only listens, and keeps what the peer sent it."""

    link: CanLink
    mavlink: PipeEnd
    status_path: Path
    commands_from_ns: float
    # One round of zero commands alone at this time (what a link sends as it closes), before commanding.
    lone_round_ns: float = math.inf
    first_command_ns: int | None = None
    status_frames_before: int = 0
    mavlink_before: bytes = b""
    status_at_first_command: dict[str, Any] = field(default_factory=dict)

    def turn(self, now_ns: int) -> None:
        if now_ns >= self.lone_round_ns:
            self.lone_round_ns = math.inf
            self.link.send_wheel_speeds([0.0] * 6)
            return
        if now_ns < self.commands_from_ns:
            self.link.poll()
            self.status_frames_before = self.link.counters.rx
            self.mavlink_before += self.mavlink.read()
            return
        if self.first_command_ns is None:
            self.first_command_ns = now_ns
            self.status_at_first_command = json.loads(self.status_path.read_text(encoding="utf-8"))
        self.link.poll()
        self.link.send_wheel_speeds([0.0] * 6)


class TurnsClock:
    """Virtual time that moves only by the peer's waits; ``turn`` runs every 20 ms of it."""

    def __init__(self, turn: Callable[[int], None]) -> None:
        self.t = T0_NS
        self._turn = turn
        self._next_turn_ns = T0_NS

    def now_ns(self) -> int:
        return self.t

    def wait(self, seconds: float) -> None:
        self.t += round(seconds * NS_PER_S)
        if self.t >= self._next_turn_ns:
            self._next_turn_ns += ROVER_PERIOD_NS
            self._turn(self.t)


def _config() -> RoverConfig:
    return rover_config_from_table(parse_toml("", "<defaults>"))


def run_against_rover(
    tmp_path: Path,
    *,
    commands_from_s: float,
    start_on_command: bool,
    seconds: float = 5.0,
    start_timeout_s: float | None = None,
    lone_round_s: float = NEVER,
) -> tuple[PeerResult, Rover]:
    config = _config()
    out = tmp_path / "peer"
    with lockstep_wires(config.can) as wires:
        sink = MemorySink()
        rover: Rover | None = None
        clock = TurnsClock(lambda now_ns: rover.turn(now_ns) if rover is not None else None)
        link = CanLink(wires.onboard_bus, VescCodec.for_profile(config.vesc), clock, sink, config=config.can)
        rover = Rover(
            link,
            wires.onboard_mavlink,
            out / "status.json",
            T0_NS + commands_from_s * NS_PER_S,
            lone_round_ns=T0_NS + lone_round_s * NS_PER_S,
        )
        result = run_peer_on_test_clock(
            scenario_with(GPS_OFF),
            config,
            out,
            clock,
            wires.sim_bus,
            wires.sim_mavlink,
            duration_ns=to_ns(seconds),
            status_path=out / "status.json",
            start_on_command=start_on_command,
            start_timeout_ns=None if start_timeout_s is None else to_ns(start_timeout_s),
        )
    return result, rover


def fault_log(truth: Path) -> list[tuple[int, str]]:
    return [
        (m.log_time_ns, str(m.message["message"]))
        for m in read_messages(truth, [topics.LOG])
        if m.message["name"] == "hil.faults"
    ]


def peer_log(truth: Path) -> list[tuple[int, int, str]]:
    return [
        (m.log_time_ns, int(m.message["level"]), str(m.message["message"]))
        for m in read_messages(truth, [topics.LOG])
        if m.message["name"] == "hil.peer"
    ]


def message_types(data: bytes) -> set[str]:
    return {m.get_type() for m in mavlink2.MAVLink(None).parse_buffer(data) or []}


@pytest.mark.parametrize("commands_from_s", [0.73, 2.5])
def test_a_fault_at_t_begins_t_after_the_rovers_first_command(tmp_path: Path, commands_from_s: float) -> None:
    result, rover = run_against_rover(tmp_path, commands_from_s=commands_from_s, start_on_command=True)
    truth = tmp_path / "peer" / "truth.mcap"
    first = rover.first_command_ns
    assert first is not None and first >= T0_NS + commands_from_s * NS_PER_S
    (injected_ns, injected), (cleared_ns, cleared) = fault_log(truth)
    assert injected.startswith("fault injected: gps/off") and cleared == "fault cleared: gps/off"
    # T after the first command (the peer's step that heard it, within one physics step), whatever the
    # rover's start; from the peer's start it would be at FAULT_AT_S.
    assert first + to_ns(FAULT_AT_S) <= injected_ns <= first + to_ns(FAULT_AT_S) + PHYSICS_NS
    assert cleared_ns - injected_ns == to_ns(0.5)
    # The peer says when the scenario started: its result, the world record, its log and its status.
    started = result.start.started_ns
    assert started is not None and first <= started <= first + PHYSICS_NS
    assert injected_ns == started + to_ns(FAULT_AT_S)
    assert read_metadata(truth)["world"] == {
        "epoch_ns": str(started),
        "start": ON_FIRST_COMMAND,
        "peer_start_ns": str(T0_NS),
    }
    # Said on the round after the first, which shows the rover is commanding (not a lone round).
    (said_ns, level, words), *_ = peer_log(truth)
    assert started < said_ns <= started + ROVER_PERIOD_NS + PHYSICS_NS and level == topics.LOG_INFO
    assert words.startswith(
        f"scenario started on the rover's first wheel command, {(started - T0_NS) / NS_PER_S:.2f} s after"
    )
    status = json.loads((tmp_path / "peer" / "status.json").read_text(encoding="utf-8"))
    assert status["scenario_start"] == ON_FIRST_COMMAND and status["scenario_started_ns"] == started
    assert status["scenario_held_s"] == pytest.approx((started - T0_NS) / NS_PER_S)
    assert not status["scenario_start_timed_out"]


def test_while_held_the_peer_streams_sensors_and_status_and_the_rover_stands_at_its_start(
    tmp_path: Path,
) -> None:
    _result, rover = run_against_rover(tmp_path, commands_from_s=2.0, start_on_command=True)
    # What a rover needs to come up: heartbeats, GPS and IMU, and its controllers' status frames.
    assert {"HEARTBEAT", "GPS_RAW_INT", "SCALED_IMU"} <= message_types(rover.mavlink_before)
    assert rover.status_frames_before >= 2.0 / 0.02 * 6 * 0.9  # six controllers' STATUS at 50 Hz
    scenario = scenario_with(GPS_OFF)
    status = rover.status_at_first_command
    assert (status["x_m"], status["y_m"]) == pytest.approx(scenario.start_xy, abs=1e-3)
    assert status["speed_mps"] == pytest.approx(0.0, abs=1e-3)
    assert status["scenario_started_ns"] is None and status["scenario_held_s"] > 1.9


def test_without_the_option_the_scenario_starts_with_the_peer_as_before(tmp_path: Path) -> None:
    result, rover = run_against_rover(tmp_path, commands_from_s=2.5, start_on_command=False)
    truth = tmp_path / "peer" / "truth.mcap"
    (injected_ns, injected), _cleared = fault_log(truth)
    assert injected.startswith("fault injected: gps/off")
    assert injected_ns == T0_NS + to_ns(FAULT_AT_S)  # before the rover's first command, at 2.5 s
    assert rover.first_command_ns is not None and rover.first_command_ns > injected_ns
    assert result.start.on == ON_PEER_START and result.start.started_ns == T0_NS
    assert read_metadata(truth)["world"] == {"epoch_ns": str(T0_NS)}
    assert read_metadata(truth)["peer"]["start"] == ON_PEER_START
    assert result.start.describe() == "scenario started with the peer"


def test_a_rover_that_never_commands_is_given_up_on_and_the_peer_says_so(tmp_path: Path) -> None:
    result, rover = run_against_rover(
        tmp_path, commands_from_s=NEVER, start_on_command=True, seconds=10.0, start_timeout_s=1.5
    )
    truth = tmp_path / "peer" / "truth.mcap"
    assert rover.first_command_ns is None
    # Stopped at the timeout, not at --duration; no fault ran (the one at 1 s would have, from the start).
    assert result.start.timed_out and result.start.started_ns is None
    assert result.simulated_s == pytest.approx(1.5, abs=0.02)
    assert fault_log(truth) == []
    (_said_ns, level, words), *_ = peer_log(truth)
    assert level == topics.LOG_ERROR and words == result.start.describe()
    assert words.startswith("no wheel command from the rover within 1.5 s of the peer's start")
    metadata = read_metadata(truth)
    assert "world" not in metadata  # no start to record: the metrics have no epoch to time carts from
    assert json.loads(metadata["runtime"]["start_json"])["scenario_start_timed_out"] is True
    status = json.loads((tmp_path / "peer" / "status.json").read_text(encoding="utf-8"))
    assert status["scenario_started_ns"] is None and status["scenario_start_timed_out"] is True


def test_a_lone_round_of_commands_does_not_start_the_scenario(tmp_path: Path) -> None:
    """The zeros a link sends as it closes (a `rover run` that stopped in its warm-up) are one round: the
    scenario stays held, and the peer still gives up on a rover that never drives."""
    result, _rover = run_against_rover(
        tmp_path,
        commands_from_s=NEVER,
        start_on_command=True,
        seconds=10.0,
        start_timeout_s=1.5,
        lone_round_s=0.5,
    )
    assert result.start.timed_out and result.start.started_ns is None
    assert result.simulated_s == pytest.approx(1.5, abs=0.02)
    assert fault_log(tmp_path / "peer" / "truth.mcap") == []


def test_a_rover_commanding_after_a_lone_round_starts_the_scenario_at_its_first_command(
    tmp_path: Path,
) -> None:
    result, rover = run_against_rover(tmp_path, commands_from_s=2.0, start_on_command=True, lone_round_s=0.5)
    first = rover.first_command_ns
    started = result.start.started_ns
    assert first is not None and started is not None and first <= started <= first + PHYSICS_NS
    (injected_ns, injected), _cleared = fault_log(tmp_path / "peer" / "truth.mcap")
    assert injected.startswith("fault injected: gps/off") and injected_ns == started + to_ns(FAULT_AT_S)


def test_a_held_world_holds_its_carts_and_faults_then_counts_them_from_its_start() -> None:
    config = _config()
    scenario = scenario_with(CART + GPS_OFF, duration_s=700.0)  # long enough for the cart to move
    clock = SimClock(T0_NS)
    buffer = io.BytesIO()
    with (
        lockstep_wires(config.can, clock=clock) as wires,
        McapRecorder(buffer) as recorder,
        SimWorld(
            scenario,
            config.vehicle,
            VescCodec.for_profile(config.vesc),
            clock,
            wires.sim_bus,
            wires.sim_mavlink,
            MemorySink(),
            scenario.seed,
        ) as world,
    ):
        world.hold()

        def cart_at(t_ns: int) -> tuple[float, float]:
            ((_cart, (x, y, _vx, _vy)),) = world.perception.moving_states(t_ns)
            return x, y

        for _ in range(500):  # 5 s held: no fault, the cart at its first waypoint
            clock.advance(PHYSICS_NS)
            world.tick(0.01)
            assert world.faults.active("gps", clock.now_ns()) is None
        assert cart_at(clock.now_ns()) == cart_at(clock.now_ns() + to_ns(10_000.0)) == (2.0, 7.0)
        world.start_at(clock.now_ns())
        started = world.epoch_ns
        world.record_start(recorder)
        with pytest.raises(ValueError, match="cannot start in the future"):
            world.start_at(clock.now_ns() + 1)
        assert started == clock.now_ns() == T0_NS + to_ns(5.0)
        assert world.faults.active("gps", started + to_ns(FAULT_AT_S) - 1) is None
        assert world.faults.active("gps", started + to_ns(FAULT_AT_S)) is not None
        # The cart walks from 600 s after the start: 3 s on, at (2, 4).
        assert cart_at(started + to_ns(599.0)) == (2.0, 7.0)
        assert np.allclose(cart_at(started + to_ns(603.0)), (2.0, 4.0))
    assert read_metadata(io.BytesIO(buffer.getvalue()))["world"] == {"epoch_ns": str(started)}


class _FakeBus:
    def shutdown(self) -> None:
        pass


class _FakeTransport:
    local_address = ("127.0.0.1", 14_551)

    def close(self) -> None:
        pass


SCENARIO = Path(__file__).resolve().parents[1] / "data" / "small_rocky.toml"


def _peer_command(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, options: list[str], timed_out: bool
) -> tuple[int, dict[str, object]]:
    """``rover hil peer`` with ``options`` on fake wires; ``run_peer`` replaced by one that says whether
    the rover commanded. Returns the exit code and what ``run_peer`` was given."""
    given: dict[str, object] = {}

    def fake_run_peer(*args: object, **kwargs: object) -> PeerResult:
        given.update(kwargs)
        start = ScenarioStart(ON_FIRST_COMMAND, T0_NS, to_ns(3.0))
        if timed_out:
            start.expired(T0_NS + to_ns(3.0))
        else:
            start.start(T0_NS + to_ns(1.25))
        timing = TimingStats.empty()
        return PeerResult(tmp_path / "truth.mcap", timing, 3.0, 0, 0, PeerStalls(50 * MS), start)

    monkeypatch.setattr(signal, "signal", lambda *_: None)  # the command's handlers: not pytest's to keep
    monkeypatch.setattr(hil.peer, "open_peer_wires", lambda *_: (_FakeBus(), _FakeTransport()))
    monkeypatch.setattr(hil.peer, "run_peer", fake_run_peer)
    code = main(["hil", "peer", str(SCENARIO), "--out", str(tmp_path / "peer"), *options])
    return code, given


def test_the_cli_option_holds_the_scenario_and_exits_1_when_the_rover_never_commanded(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, given = _peer_command(monkeypatch, tmp_path, ["--start-on-command", "--start-timeout", "3"], True)
    assert code == 1
    assert given["start_on_command"] is True and given["start_timeout_ns"] == to_ns(3.0)
    assert "no wheel command from the rover within 3 s" in " ".join(capsys.readouterr().out.split())
    code, given = _peer_command(monkeypatch, tmp_path, ["--start-on-command"], False)
    assert code == 0 and given["start_timeout_ns"] == to_ns(120.0)
    out = " ".join(capsys.readouterr().out.split())
    assert "scenario started on the rover's first wheel command, 1.25 s after the peer" in out
    code, given = _peer_command(monkeypatch, tmp_path, [], False)
    assert code == 0 and given["start_on_command"] is False


def test_a_start_timeout_without_the_option_is_bad_input(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, given = _peer_command(monkeypatch, tmp_path, ["--start-timeout", "3"], False)
    assert code == 2 and given == {}
    assert "--start-timeout is how long --start-on-command waits" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exited:
        main(["hil", "peer", str(SCENARIO), "--start-on-command", "--start-timeout", "0"])
    assert exited.value.code == 2


def test_a_scenario_start_refuses_a_mode_it_does_not_know() -> None:
    with pytest.raises(ValueError, match="first wheel command"):
        ScenarioStart("whenever", 0)
    with pytest.raises(ValueError, match="must be > 0"):
        ScenarioStart(ON_FIRST_COMMAND, 0, 0)


def test_a_held_peers_world_record_still_gives_the_metrics_its_epoch(tmp_path: Path) -> None:
    # The held peer's world record has more entries (what started it, when the peer did): the metrics
    # still time the carts from its epoch_ns, the scenario's start, as for a peer that did not hold.
    _write_rover(tmp_path / "rover.mcap")
    start = ScenarioStart(ON_FIRST_COMMAND, WORLD_START_NS - to_ns(30.0))
    held = {"epoch_ns": str(WORLD_START_NS), **start.record()}
    _write_truth(tmp_path / "truth.mcap", held)
    metrics = realtime_metrics(tmp_path / "rover.mcap", tmp_path / "truth.mcap")
    assert metrics.obstacles_encountered == 1 and not metrics.problems, metrics
