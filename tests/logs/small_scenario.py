"""The smallest scenario text that loads (10 x 10 m of procedural ground, a start and a goal), for tests
that add one table or key to it and read the error."""

from __future__ import annotations

from pathlib import Path

from hil.scenario import Scenario, scenario_from_table
from logs.settings import parse_toml

SMALL_SCENARIO = """
name = "small"
duration_s = 60.0
[terrain]
kind = "procedural"
size_m = [10.0, 10.0]
[start]
xy = [2.0, 2.0]
[[goals]]
xy = [8.0, 8.0]
"""


def load_text(text: str, source: str = "scenario.toml") -> Scenario:
    """The scenario ``text`` describes, read as if from a file named ``source`` (ConfigError if bad)."""
    return scenario_from_table(parse_toml(text, source), text, base_dir=Path("."))
