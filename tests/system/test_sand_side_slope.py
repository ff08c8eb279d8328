"""scenarios/sand-side-slope.toml, out along a hillside's contour across a strip of sand worse than the
table's, and back: believing the table, the rover slides downhill on the sand, learns that the sand grips
less (navigator.slide_learning), drives on off the strip, and plans the way back round the slope, on the
flat: it never slides again. With learning off it crosses the strip again on the way back and slides again."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from hil.scenario import load_scenario
from hil.trial import run_trial
from logs.reader import read_messages
from logs.settings import parse_toml
from logs.topics import NAVIGATOR_LEARNED, NAVIGATOR_PATH, SAFETY_EVENTS, TRUTH_POSE
from navigator.config import rover_config_from_table

ROOT = Path(__file__).resolve().parents[2]
NO_LEARNING = "[planner]\nlearn_traction = false\n"
SAND_X = (15.0, 25.0)  # scripts/make_sand_side_slope.py: the strip, on the hillside for y 3-47 m
SLOPE_Y = (3.0, 47.0)
TILT_DEG = 12.5


@pytest.mark.parametrize("learning", [True, False], ids=["believes-the-table", "no-learning"])
def test_sliding_on_the_sand_it_learns_and_plans_the_way_back_off_the_slope(
    tmp_path: Path, learning: bool
) -> None:
    scenario = load_scenario(ROOT / "scenarios" / "sand-side-slope.toml")
    # Out by ~54 s (it slides from ~23 s); the way back slides, without learning, from ~70 s.
    scenario = dataclasses.replace(scenario, duration_s=100.0)
    config = rover_config_from_table(parse_toml("" if learning else NO_LEARNING, "<config>"))
    mcap = run_trial(scenario, config, tmp_path / "t").mcap_path
    topics = [SAFETY_EVENTS, NAVIGATOR_LEARNED, NAVIGATOR_PATH, TRUTH_POSE]
    messages = [(m.topic, m.log_time_ns, m.message) for m in read_messages(mcap, topics=topics)]
    told = [
        (t, m["detail"])
        for topic, t, m in messages
        if topic == SAFETY_EVENTS and m["kind"] == "learned.terrain"
    ]
    arrived_ns = min(
        t for topic, t, m in messages if topic == SAFETY_EVENTS and m["kind"] == "guidance.arrived"
    )
    slides_back = [
        abs(m.get("lateral_speed_mps", 0.0))
        for topic, t, m in messages
        if topic == TRUTH_POSE and t > arrived_ns
    ]
    back = next(m for topic, t, m in messages if topic == NAVIGATOR_PATH and t >= arrived_ns)
    on_the_sandy_slope = [
        (p["position"]["x"], p["position"]["y"])
        for p in back["poses"]
        if SAND_X[0] <= p["position"]["x"] <= SAND_X[1] and SLOPE_Y[0] < p["position"]["y"] < SLOPE_Y[1]
    ]
    if learning:
        ((learned_ns, detail),) = told
        assert detail.startswith(f"slid sideways across {TILT_DEG}") and "on sandy" in detail
        assert learned_ns < arrived_ns
        (record,) = [m for topic, _t, m in messages if topic == NAVIGATOR_LEARNED]
        assert math.degrees(record["slope_rad"]) == pytest.approx(TILT_DEG, abs=0.5)
        assert on_the_sandy_slope == [] and max(slides_back) < 0.01
    else:
        assert told == []
        assert on_the_sandy_slope and max(slides_back) > 0.3
