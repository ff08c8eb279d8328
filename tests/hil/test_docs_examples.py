"""docs/hil.md's scenario examples are real: each block loads as a scenario, and the fault table lists
exactly the targets, kinds and parameters the parser takes."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from hil.faults import SUPPORTED, faults_from_tables
from hil.scenario import load_scenario
from logs.settings import ConfigError, Table

DOC = Path(__file__).resolve().parents[2] / "docs" / "hil.md"
TEXT = DOC.read_text(encoding="utf-8")
BLOCKS = re.findall(r"^```toml\n(.*?)^```$", TEXT, flags=re.MULTILINE | re.DOTALL)
BASE = next(block for block in BLOCKS if block.startswith("name = "))

# A valid value of every fault parameter, to ask the parser which (target, kind) takes which.
PARAMETER_SAMPLES: dict[str, Any] = {
    "offset_m": [1.0, 0.0],
    "delay_s": 0.1,
    "factor": 2.0,
    "probability": 0.5,
    "gyro_bias_rps": [0.0, 0.0, 0.01],
    "accel_bias_mps2": [0.1, 0.0, 0.0],
    "controller": 1,
    "sag_v": 1.0,
    "extra_resistance_ohm": 0.1,
}


def test_the_doc_has_a_complete_scenario_and_fragments() -> None:
    assert len(BLOCKS) >= 4 and BASE.count("[[obstacles]]") >= 1 and "known = false" in BASE


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_every_toml_block_loads_as_a_scenario(index: int, tmp_path: Path) -> None:
    block = BLOCKS[index]
    path = tmp_path / "example.toml"
    path.write_text(block if block is BASE else f"{BASE}\n{block}", encoding="utf-8")
    load_scenario(path)


def test_the_fault_example_has_every_kind_of_every_target(tmp_path: Path) -> None:
    (faults_block,) = [block for block in BLOCKS if "[[faults]]" in block]
    path = tmp_path / "faults.toml"
    path.write_text(f"{BASE}\n{faults_block}", encoding="utf-8")
    shown = {(fault.target, fault.kind) for fault in load_scenario(path).faults}
    assert shown == {(target, kind) for target, kinds in SUPPORTED.items() for kind in kinds}


def _accepted_parameters(target: str, kind: str) -> set[str]:
    accepted = set()
    for name, value in PARAMETER_SAMPLES.items():
        data = {"target": target, "kind": kind, name: value}
        if name != "offset_m" and (target, kind) == ("gps", "wrong"):
            data["offset_m"] = PARAMETER_SAMPLES["offset_m"]  # required there
        try:
            faults_from_tables([Table(data, "probe", "faults[0]")], 60.0)
        except ConfigError as err:
            assert err.key == f"faults[0].{name}" and "unknown key" in err.problem, err
            continue
        accepted.add(name)
    return accepted


def test_the_fault_table_lists_what_the_parser_takes() -> None:
    rows = re.findall(r"^\| (\w+) \| (\w+) \| [^|]+ \| ([^\n]+) \|$", TEXT, flags=re.MULTILINE)
    documented = {(target, kind): set(re.findall(r"`(\w+)`", params)) for target, kind, params in rows}
    documented.pop(("target", "kind"), None)  # the header row
    assert documented.keys() == {(target, kind) for target, kinds in SUPPORTED.items() for kind in kinds}
    for (target, kind), names in documented.items():
        assert names == _accepted_parameters(target, kind), (target, kind)
