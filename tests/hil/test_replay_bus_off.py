"""``hil.replay`` of a trial with a CAN bus-off (a ``can`` ``off`` fault): the controller's error frames are
recorded and delivered again, and a lockstep trial's refused sends are refused again.

small_rocky_bus_off (tests/hil/conftest.py's ``trials``): bus-off 2-3 s while driving, and from 5 s until
the trial ends, so the stack closes (its six zero commands) while its controller is off the bus.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import can
import pytest

from firmware_bridge.can_health import CAN_ERR_BUSOFF, CAN_ERR_CRTL, CAN_ERR_RESTARTED
from hil.bus_off import error_frame
from hil.lockstep_bus import lockstep_bus_pair
from hil.replay import replay_recording
from hil.replay_bus_off import RecordedBusOffEnd
from hil.scenario import load_scenario
from logs import topics
from logs.reader import read_messages
from tests.hil.replay_trials import DATA, config_of, digests, rover_run_config
from tests.mcap_rewrite import rewrite

S = 1_000_000_000
TRIAL = "small_rocky_bus_off"
ERROR_MARK = b'"error":true'


def _records(path: Path, topic: str) -> list[tuple[int, dict[str, Any]]]:
    return [(m.log_time_ns, m.message) for m in read_messages(path, [topic])]


def _error_frames(path: Path) -> list[tuple[int, int]]:
    return [(t, m["id"]) for t, m in _records(path, topics.CAN_FRAMES) if m.get("error") is True]


def _bus_events(path: Path) -> list[tuple[int, str]]:
    kinds = ("can_bus_off", "can_recovering", "can_recovered")
    return [(t, m["kind"]) for t, m in _records(path, topics.SAFETY_EVENTS) if m["kind"] in kinds]


def test_a_bus_off_trial_replays_to_itself_byte_for_byte(trials: dict[str, Path], tmp_path: Path) -> None:
    trial, out = trials[TRIAL], tmp_path / "replay.mcap"
    # The trial's link recorded what its controller reported, at the first read into and after each fault.
    assert _error_frames(trial) == [
        (2 * S, CAN_ERR_BUSOFF),
        (3 * S, CAN_ERR_RESTARTED),
        (5 * S, CAN_ERR_BUSOFF),
    ]
    result = replay_recording(trial, config_of(), out)
    assert digests(out) == digests(trial)
    assert result.wheel_commands_compared == result.ticks > 0 and result.wheel_commands_differing == 0
    assert result.can_error_frames == 3 and result.rejected_inputs == 0 and not result.partial
    # The stack closed bus-off: its zero round was refused, frame by frame, as the trial's end refused it.
    assert result.can_sends_refused == 6
    assert not [t for t, m in _records(out, topics.CAN_FRAMES) if m["direction"] == "tx" and t >= 5 * S]


def test_a_rover_run_recordings_error_frames_are_fed_and_no_send_is_refused(
    trials: dict[str, Path], tmp_path: Path
) -> None:
    """Beside the real-time peer the rover's bus took every send (its link withheld its rounds itself
    once bus-off): the error frames are fed, the link goes bus-off at their times, nothing is refused."""
    run = rewrite(
        trials[TRIAL],
        tmp_path / "run.mcap",
        keep=lambda topic: not topic.startswith("truth/"),
        metadata=lambda name, data: {**data, "mode": "rover-run"} if name == "trial" else data,
    )
    out = tmp_path / "replay.mcap"
    result = replay_recording(run, rover_run_config(), out)
    assert result.can_error_frames == 3 and result.can_sends_refused == 0
    assert [(t, kind) for t, kind in _bus_events(out) if kind != "can_recovered"] == [
        (2 * S, "can_bus_off"),
        (3 * S, "can_recovering"),
        (5 * S, "can_bus_off"),
    ]
    # The zero round the stack sends as it closes, bus-off, went out: `rover run`'s bus did not refuse it.
    closing = [t for t, m in _records(out, topics.CAN_FRAMES) if m["direction"] == "tx" and t >= 5 * S]
    assert len(closing) == 6


def test_a_recording_without_error_frame_records_replays_as_before_them(
    trials: dict[str, Path], tmp_path: Path
) -> None:
    """A recording made before error frames were recorded: nothing tells the replayed link of the bus-off,
    so it drives on where the trial's stopped (the limit docs/reports.md names)."""
    old = rewrite(
        trials[TRIAL],
        tmp_path / "old.mcap",
        drop=lambda topic, payload: topic == topics.CAN_FRAMES and ERROR_MARK in payload,
    )
    scenario = load_scenario(DATA / f"{TRIAL}.toml")
    result = replay_recording(old, config_of(), tmp_path / "replay.mcap", scenario=scenario)
    assert result.can_error_frames == 0 and result.can_sends_refused == 0 and not result.partial
    assert result.wheel_commands_differing > 0
    assert result.first_difference_s == pytest.approx(2.0, abs=0.05)
    assert _bus_events(tmp_path / "replay.mcap") == []


def test_a_malformed_error_frame_record_is_counted_logged_and_skipped(
    trials: dict[str, Path], tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    spoiled = rewrite(
        trials[TRIAL],
        tmp_path / "spoiled.mcap",
        data=lambda topic, t_ns, payload: (
            payload.replace(ERROR_MARK, b'"error":"yes"')
            if topic == topics.CAN_FRAMES and t_ns == 2 * S
            else payload
        ),
    )
    scenario = load_scenario(DATA / f"{TRIAL}.toml")
    with caplog.at_level(logging.WARNING, logger="hil.replay"):
        result = replay_recording(spoiled, config_of(), tmp_path / "replay.mcap", scenario=scenario)
    assert result.rejected_inputs == 1 and result.partial and result.can_error_frames == 2
    (line,) = [r.getMessage() for r in caplog.records if r.name == "hil.replay"]
    assert "can/frames record at 2000000000 ns not fed" in line and "error='yes'" in line


def test_the_replays_end_refuses_sends_from_a_busoff_to_the_next_restarted() -> None:
    rover, sim = lockstep_bus_pair("recorded-bus-off")
    end = RecordedBusOffEnd(rover)
    command = can.Message(arbitration_id=0x301, is_extended_id=True, data=bytes(4))
    try:
        end.send_all([command])
        end.heard(error_frame(CAN_ERR_CRTL, 0))  # error-passive or the like: the link judges it, no refusal
        end.send(command)
        assert len(sim.recv_all()) == 2
        end.heard(error_frame(CAN_ERR_BUSOFF, 0))
        with pytest.raises(can.CanOperationError, match="bus-off"):
            end.send_all([command, command])
        with pytest.raises(can.CanOperationError, match="bus-off"):
            end.send(command)
        assert sim.recv_all() == () and end.refused == 1
        end.heard(error_frame(CAN_ERR_RESTARTED, 0))
        end.send(command)
        sim.send(command)
        assert len(sim.recv_all()) == 1 and end.recv_all() == [command]
    finally:
        end.shutdown()
        rover.shutdown()
        sim.shutdown()


def test_rover_logs_replay_names_the_error_frames_and_the_refused_sends(
    trials: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rover_cli.main import main

    config = tmp_path / "rover.toml"
    config.write_text("")
    out = tmp_path / "replay.mcap"
    assert (
        main(["logs", "replay", str(trials[TRIAL]), "--config", str(config), "--out", str(out), "--json"])
        == 0
    )
    document = json.loads(capsys.readouterr().out)
    assert document["inputs"]["can_error_frames"] == 3 and document["can_sends_refused"] == 6
    assert document["wheel_commands_differing"] == 0
