"""The obstacle encounter margin: one default (docs/metrics.md), set per scenario, recorded with the trial."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader

from hil.scenario import load_scenario
from hil.trial import write_header
from logs.metrics import DEFAULT_ENCOUNTER_MARGIN_M
from logs.recorder import McapRecorder
from logs.settings import ConfigError, parse_toml
from navigator.config import rover_config_from_table

DATA = Path(__file__).resolve().parents[1] / "data"


def _scenario_file(tmp_path: Path, first_line: str) -> Path:
    path = tmp_path / "scenario.toml"
    path.write_text(
        first_line + "\n" + (DATA / "small_rocky.toml").read_text(encoding="utf-8"), encoding="utf-8"
    )
    return path


def _recorded_scenario(tmp_path: Path, scenario_path: Path) -> dict[str, str]:
    scenario = load_scenario(scenario_path)
    recording = tmp_path / "header.mcap"
    with McapRecorder(recording) as recorder:
        write_header(recorder, scenario, rover_config_from_table(parse_toml("", "<defaults>")), 1)
    with recording.open("rb") as stream:
        return {m.name: dict(m.metadata) for m in make_reader(stream).iter_metadata()}["scenario"]


def test_a_scenario_sets_the_margin_and_the_recording_keeps_it(tmp_path: Path) -> None:
    path = _scenario_file(tmp_path, "encounter_margin_m = 3.0")
    assert load_scenario(path).encounter_margin_m == 3.0
    assert float(_recorded_scenario(tmp_path, path)["encounter_margin_m"]) == 3.0


def test_the_default_margin_is_the_documented_one(tmp_path: Path) -> None:
    path = _scenario_file(tmp_path, "")
    assert DEFAULT_ENCOUNTER_MARGIN_M == 1.5  # docs/metrics.md and docs/hil.md say so
    assert float(_recorded_scenario(tmp_path, path)["encounter_margin_m"]) == DEFAULT_ENCOUNTER_MARGIN_M


@pytest.mark.parametrize("bad", ["0.0", "-1.0", '"wide"'])
def test_a_margin_that_is_not_a_positive_length_is_refused(tmp_path: Path, bad: str) -> None:
    with pytest.raises(ConfigError, match=r"encounter_margin_m.*(must be > 0|expected a number)"):
        load_scenario(_scenario_file(tmp_path, f"encounter_margin_m = {bad}"))
