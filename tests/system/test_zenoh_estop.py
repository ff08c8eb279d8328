"""Issue 7: an e-stop published on the rover's Zenoh command key stops the rover in HIL."""

from __future__ import annotations

import time

import pytest

from hil.trial import run_trial
from logs import topics
from logs.clock import SimClock
from logs.commands import ZenohCommandReceiver, send_command
from logs.reader import read_messages
from tests.system.zenoh_pair import open_pair

pytestmark = pytest.mark.realtime  # the e-stop must arrive over Zenoh while the trial runs

ESTOP_AT = 0.2  # share of the scenario's duration: the rover is driving by then


def test_estop_on_command_key_stops_the_rover(small_scenario, default_config, tmp_path):
    rover, ground = open_pair()
    # The receiver stamps arrivals with a clock; the trial's own clock is inside run_trial, and the
    # stamp only feeds the ground-link failsafe, which is off by default.
    receiver = ZenohCommandReceiver(rover, default_config.rover_id, SimClock())
    sent = {"done": False}

    def on_progress(share: float) -> None:
        if sent["done"] or share < ESTOP_AT:
            return
        sent["done"] = True
        deadline = time.monotonic() + 10.0
        while receiver.accepted == 0 and time.monotonic() < deadline:
            send_command(ground, default_config.rover_id, "estop")
            time.sleep(0.05)  # the simulated clock stands still while we wait: lockstep
        assert receiver.accepted > 0, "the rover never received the e-stop"

    try:
        result = run_trial(
            small_scenario, default_config, tmp_path / "trial", commands=receiver, on_progress=on_progress
        )
    finally:
        receiver.close()
        ground.close()
        rover.close()

    assert sent["done"]
    events = [m for m in read_messages(result.mcap_path, topics=[topics.SAFETY_EVENTS])]
    estops = [m for m in events if m.message["kind"] == "failsafe.estop"]
    assert len(estops) == 1
    estop_ns = estops[0].log_time_ns
    assert result.end_reason != "arrived"
    # After the e-stop every wheel command is zero and the true rover comes to rest within a second.
    commands = read_messages(result.mcap_path, topics=[topics.WHEELS_COMMAND])
    after = [m.message for m in commands if m.log_time_ns > estop_ns]
    assert after and all(speed == 0.0 for m in after for speed in m["speed_mps"])
    truth = read_messages(result.mcap_path, topics=[topics.TRUTH_POSE])
    settled = [m.message["speed_mps"] for m in truth if m.log_time_ns > estop_ns + 1_000_000_000]
    assert settled and max(abs(v) for v in settled) < 0.05
