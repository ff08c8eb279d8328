"""scenarios/sand-dune.toml, the ground's sand worse than the table's: the planner's belief decides the
route. Believing the table, it drives at the dune, digs in at the foot and the no_progress failsafe holds
it; believing the measured sand (the rover config's [terrain_classes.sandy]), it goes round and arrives."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from hil.scenario import load_scenario
from hil.trial import run_trial
from logs.reader import read_messages
from logs.settings import parse_toml
from logs.topics import SAFETY_EVENTS
from navigator.config import rover_config_from_table

ROOT = Path(__file__).resolve().parents[2]
MEASURED = "[terrain_classes.sandy]\nfriction_mu = 0.25\nlateral_resistance = 0.2\n"


def _trial(config_text: str, out: Path) -> tuple[bool, list[str]]:
    scenario = load_scenario(ROOT / "scenarios" / "sand-dune.toml")
    # The believing-the-table rover holds by ~23 s, the other arrives by ~74 s: 80 s shows both.
    scenario = dataclasses.replace(scenario, duration_s=80.0)
    config = rover_config_from_table(parse_toml(config_text, "<config>"))
    result = run_trial(scenario, config, out)
    kinds = [m.message["kind"] for m in read_messages(result.mcap_path, topics=[SAFETY_EVENTS])]
    return result.end_reason == "arrived", kinds


def test_believing_the_table_digs_in_and_holds_believing_the_measured_sand_goes_round(tmp_path: Path) -> None:
    arrived, kinds = _trial("", tmp_path / "table")
    assert not arrived
    assert "failsafe.no_progress" in kinds
    arrived, kinds = _trial(MEASURED, tmp_path / "measured")
    assert arrived
    assert "failsafe.no_progress" not in kinds
