"""What a trial learned of its ground carried to the next: scenarios/sand-dune.toml, the planner believing
the table's sand. The first run digs in, learns (navigator/learned) and goes round; `rover logs learned`
turns its recording into the rover config's [terrain_classes] tables; a run on that config goes round from
the start, never held, learning nothing new, and arrives sooner."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from hil.scenario import load_scenario
from hil.trial import TrialResult, run_trial
from logs.learned_terrain import read_learned
from logs.reader import read_messages
from logs.settings import parse_toml
from logs.topics import SAFETY_EVENTS
from navigator.config import rover_config_from_table
from rover_cli.main import main

ROOT = Path(__file__).resolve().parents[2]


def _trial(config_text: str, out: Path) -> tuple[TrialResult, list[str]]:
    scenario = load_scenario(ROOT / "scenarios" / "sand-dune.toml")
    scenario = dataclasses.replace(scenario, duration_s=100.0)  # round the dune by ~94 s after learning
    result = run_trial(scenario, rover_config_from_table(parse_toml(config_text, "<config>")), out)
    kinds = [m.message["kind"] for m in read_messages(result.mcap_path, topics=[SAFETY_EVENTS])]
    return result, kinds


def test_a_learning_written_into_the_config_spares_the_next_run_the_dig_in(tmp_path: Path) -> None:
    first, first_kinds = _trial("", tmp_path / "first")
    assert first.end_reason == "arrived" and "learned.terrain" in first_kinds
    learned = read_learned([first.mcap_path]).learnings
    assert [(x.class_name, x.field) for x in learned] == [("sandy", "friction_mu")]
    assert learned[0].value < learned[0].believed

    tables = tmp_path / "learned.toml"
    assert main(["logs", "learned", str(first.mcap_path), "--out", str(tables)]) == 0
    second, second_kinds = _trial(tables.read_text(), tmp_path / "second")
    assert second.end_reason == "arrived"
    assert "failsafe.no_progress" not in second_kinds and "learned.terrain" not in second_kinds
    assert not read_learned([second.mcap_path]).learnings
    assert first.arrived_s is not None and second.arrived_s is not None
    assert second.arrived_s < first.arrived_s - 10.0  # ~74 s against ~94 s
