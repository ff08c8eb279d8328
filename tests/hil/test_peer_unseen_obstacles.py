"""``rover hil peer`` says which of its scenario's obstacles the rover in another process cannot see.

``rover run`` has no perception input (nothing hands it ``hil.perception_sim``'s observations, as
``hil.trial`` does in lockstep): it plans on the map the peer wrote, which holds only the known obstacles.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.lockstep import lockstep_wires
from hil.scenario import Scenario
from logs import topics
from logs.clock import NS_PER_S
from logs.reader import read_messages
from logs.settings import parse_toml
from navigator.config import rover_config_from_table
from tests.hil.world_harness import StepClock, run_peer_on_test_clock, scenario_with

HIDDEN_ROCK = """
[[obstacles]]
id = "hidden-rock"
xy = [9.0, 2.5]
radius_m = 0.4
known = false
"""
CART = """
[[moving_obstacles]]
id = "cart"
radius_m = 0.4
speed_mps = 0.5
waypoints = [[8.0, 8.5], [12.0, 8.5]]
"""


def _peer_warnings(scenario: Scenario, out: Path, caplog: pytest.LogCaptureFixture) -> tuple[str, list[str]]:
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    with lockstep_wires(config.can) as wires:
        run_peer_on_test_clock(
            scenario, config, out, StepClock(), wires.sim_bus, wires.sim_mavlink, duration_ns=NS_PER_S // 10
        )
    logged = " ".join(r.getMessage() for r in caplog.records if r.name == "hil.peer")
    recorded = [
        message.message["message"]
        for message in read_messages(out / "truth.mcap", topics={topics.LOG})
        if message.message["name"] == "hil.peer"
    ]
    return logged, recorded


def test_hidden_and_moving_obstacles_are_named_as_unseen_by_the_rover(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    # carts.toml run this way: the rover drove through the carts' lanes without ever stopping (no BLOCKED,
    # 30 s instead of lockstep's 38-46 s), and nothing had said it could not see them.
    logged, recorded = _peer_warnings(scenario_with(HIDDEN_ROCK + CART), tmp_path / "peer", caplog)
    for said in (logged, " ".join(recorded)):
        assert "the rover cannot see" in said
        assert "hidden obstacle 'hidden-rock' (known = false)" in said and "moving obstacle 'cart'" in said
        assert "no perception input" in said


def test_a_scenario_with_only_known_obstacles_draws_no_such_warning(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    logged, recorded = _peer_warnings(scenario_with(""), tmp_path / "peer", caplog)
    assert "cannot see" not in logged
    assert not any("cannot see" in message for message in recorded)
