"""What a faulty trial leaves for the analyst: events on change, not per tick, that agree with the
navigator's state, and the onboard stack's warnings on the recording's ``log`` topic.

The scenario: a cart crossing the line holds the rover (BLOCKED) twice for seconds, and a 3 m GPS glitch
the estimator gates out (its warnings go to the log).
"""

from __future__ import annotations

import re
from itertools import pairwise
from pathlib import Path

import pytest

from hil.scenario import load_scenario
from hil.trial import TrialResult, run_trial
from logs import topics
from logs.reader import read_messages
from navigator.config import RoverConfig

DATA = Path(__file__).resolve().parents[1] / "data"


@pytest.fixture(scope="module")
def cart_trial(default_config: RoverConfig, tmp_path_factory: pytest.TempPathFactory) -> TrialResult:
    scenario = load_scenario(DATA / "sandy_cart_glitch.toml")
    return run_trial(scenario, default_config, tmp_path_factory.mktemp("cart"))


def _stamp_ns(message: dict) -> int:
    return int(message["timestamp"]["sec"]) * 1_000_000_000 + int(message["timestamp"]["nsec"])


def test_blocked_is_one_event_per_wait_not_one_per_tick(cart_trial):
    states = [r.message["mode"] for r in read_messages(cart_trial.mcap_path, topics=[topics.NAVIGATOR_STATE])]
    waits = sum(1 for before, now in pairwise(states) if now == "BLOCKED" != before)
    assert waits >= 2, "the cart never held the rover: the scenario no longer tests this"
    assert states.count("BLOCKED") > 100  # seconds of waiting at 50 Hz
    events = [r.message for r in read_messages(cart_trial.mcap_path, topics=[topics.SAFETY_EVENTS])]
    blocked = [e for e in events if e["kind"] == "guidance.blocked" and "cart-a" in e["detail"]]
    assert len(blocked) == waits
    assert sum(1 for e in events if e["detail"].startswith("way clear: moving obstacle cart-a")) == waits


def test_safety_mode_events_say_what_guidance_says(cart_trial):
    state_at = {
        _stamp_ns(r.message): r.message["mode"]
        for r in read_messages(cart_trial.mcap_path, topics=[topics.NAVIGATOR_STATE])
    }
    events = [r.message for r in read_messages(cart_trial.mcap_path, topics=[topics.SAFETY_EVENTS])]
    to_idle = [e for e in events if e["kind"] == "mode" and "-> IDLE" in e["detail"]]
    assert len(to_idle) >= 3  # twice blocked, then arrived
    for event in to_idle:
        guidance_mode = state_at[_stamp_ns(event)]
        assert f"-> IDLE: guidance {guidance_mode}: " in event["detail"], event
    assert any("guidance BLOCKED: moving obstacle cart-a on the path" in e["detail"] for e in to_idle)


def test_the_onboard_stacks_warnings_are_on_the_log_topic(cart_trial):
    lines = [r.message for r in read_messages(cart_trial.mcap_path, topics=[topics.LOG])]
    assert any(line["name"] == "hil.faults" for line in lines)  # the simulator's own, as before
    gated = [
        line
        for line in lines
        if line["name"] == "estimator.estimator" and "rejected a sample (gps_gated" in line["message"]
    ]
    assert gated and all(line["level"] == 3 for line in gated)
    # The residual in metres to the centimetre, not a float's 16 digits.
    assert re.search(r"residual \(-?\d+\.\d\d, -?\d+\.\d\d\) m$", gated[0]["message"]), gated[0]["message"]
