"""Perception through a ring of rangefinders (``[sensors] perception = "rangefinders"``): the simulated
autopilot sends DISTANCE_SENSOR, the onboard stack tracks obstacles from those readings alone. The rock
missing from the map on the straight line to the goal is found, reported near where it is, and driven
around; the trial is as deterministic as any."""

from __future__ import annotations

import base64
import json
import math
import statistics
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink2

from hil.scenario import load_scenario, with_perception
from hil.trial import TrialResult, run_trial
from logs import topics
from logs.reader import read_messages, read_metadata
from logs.settings import parse_toml
from navigator.config import RoverConfig, rover_config_from_table

DATA = Path(__file__).resolve().parents[1] / "data"
ROCK_XY, ROCK_RADIUS_M = (7.0, 5.0), 0.6
# The default ring (front, front-right, front-left, right, left), all at the rover's centre.
CONFIG = "[perception]\nrangefinders = [{id = 0}, {id = 1}, {id = 2}, {id = 3}, {id = 4}]\n"


def _config() -> RoverConfig:
    return rover_config_from_table(parse_toml(CONFIG, "<rangefinders>"))


def _trial(out: Path) -> TrialResult:
    return run_trial(
        with_perception(load_scenario(DATA / "hidden_rock.toml"), "rangefinders"), _config(), out
    )


def test_a_lockstep_trial_finds_the_hidden_rock_through_rangefinders_alone(tmp_path: Path) -> None:
    result = _trial(tmp_path / "trial")
    assert result.metrics.goal_reached and result.metrics.collisions == 0, result.metrics
    seen = [
        obstacle
        for message in read_messages(result.mcap_path, topics={topics.PERCEPTION_OBSTACLES})
        for obstacle in message.message["obstacles"]
    ]
    assert seen and all(o["id"].startswith("scan-") for o in seen)  # tracks of its own, no objects
    # Static, every one: a beam's disc lies on its axis wherever in the cone the echo was, and judged on
    # those the rock seemed to move as the cones swept it (docs/planning.md "Perception from rangefinders").
    assert all(o["vx"] == 0.0 and o["vy"] == 0.0 for o in seen)
    # Near where it is: a beam sees the rock's near side, so a report's centre lies about its radius from
    # the rock's, and its disc touches the rock, to 25 cm.
    gaps = [math.hypot(o["x"] - ROCK_XY[0], o["y"] - ROCK_XY[1]) for o in seen]
    assert statistics.median(gaps) < ROCK_RADIUS_M + 0.2
    assert all(gap < ROCK_RADIUS_M + o["radius_m"] + 0.25 for gap, o in zip(gaps, seen, strict=True))
    readings = [
        m
        for m in read_messages(result.mcap_path, topics={topics.MAVLINK_RAW})
        if m.message["direction"] == "rx" and m.message["msgid"] == mavlink2.MAVLINK_MSG_ID_DISTANCE_SENSOR
    ]
    assert len(readings) >= 5 * 10 * 12  # five sensors at 10 Hz over a drive of more than 12 s
    stats = list(read_messages(result.mcap_path, topics={topics.MAVLINK_STATS}))
    assert sum(m.message["beams"] for m in stats) > 0 and all(m.message["beams_rejected"] == 0 for m in stats)
    events = [m.message["kind"] for m in read_messages(result.mcap_path, topics={topics.SAFETY_EVENTS})]
    assert "perception_lost" not in events
    scenario_record = read_metadata(result.mcap_path)["scenario"]
    assert scenario_record["perception"] == "rangefinders"
    ring = json.loads(scenario_record["perception_json"])
    assert ring["rangefinder_yaw_deg"] == [0, 45, 315, 90, 270] and ring["rangefinder_fov_deg"] == 15.0


def test_a_rangefinder_trial_is_deterministic(tmp_path: Path) -> None:
    first, second = (
        [(m.topic, m.log_time_ns, m.message) for m in read_messages(_trial(tmp_path / name).mcap_path)]
        for name in ("a", "b")
    )
    assert first == second


# A nose sonar, two front corner ones turned 30 degrees outward and two side ones turned 100 degrees out
# (yaw_deg counter-clockwise: negative on the right), as a real vehicle might carry them: the turned ones
# say MAV_SENSOR_ROTATION_CUSTOM with their quaternion; the config places each by id.
CORNERS = (
    "rangefinders = [{yaw_deg = 0.0, forward_m = 0.5}, {yaw_deg = -30.0, forward_m = 0.45, left_m = -0.3},"
    " {yaw_deg = 30.0, forward_m = 0.45, left_m = 0.3}, {yaw_deg = -100.0, left_m = -0.35},"
    " {yaw_deg = 100.0, left_m = 0.35}]"
)
CORNERS_CONFIG = (
    "[perception]\nrangefinders = [{id = 0, forward_m = 0.5}, {id = 1, forward_m = 0.45, left_m = -0.3},"
    " {id = 2, forward_m = 0.45, left_m = 0.3}, {id = 3, left_m = -0.35}, {id = 4, left_m = 0.35}]\n"
)


def test_a_ring_of_sensors_each_placed_and_turned_its_own_way_finds_the_rock(tmp_path: Path) -> None:
    text = (
        (DATA / "hidden_rock.toml")
        .read_text()
        .replace('perception = "scan"', f'perception = "rangefinders"\n{CORNERS}')
    )
    (tmp_path / "corners.toml").write_text(text)
    config = rover_config_from_table(parse_toml(CORNERS_CONFIG, "<corners>"))
    result = run_trial(load_scenario(tmp_path / "corners.toml"), config, tmp_path / "trial")
    assert result.metrics.goal_reached and result.metrics.collisions == 0, result.metrics
    sent = [
        mavlink2.MAVLink(None).decode(bytearray(base64.b64decode(m.message["data"])))
        for m in read_messages(result.mcap_path, topics={topics.MAVLINK_RAW})
        if m.message["direction"] == "rx" and m.message["msgid"] == mavlink2.MAVLINK_MSG_ID_DISTANCE_SENSOR
    ]
    custom = mavlink2.MAV_SENSOR_ROTATION_CUSTOM
    assert {(msg.id, msg.orientation) for msg in sent} == {
        (0, 0),
        (1, custom),
        (2, custom),
        (3, custom),
        (4, custom),
    }
    stats = list(read_messages(result.mcap_path, topics={topics.MAVLINK_STATS}))
    assert all(m.message["beams_rejected"] == 0 and m.message["beams_unused"] == 0 for m in stats)
    seen = [
        obstacle
        for message in read_messages(result.mcap_path, topics={topics.PERCEPTION_OBSTACLES})
        for obstacle in message.message["obstacles"]
    ]
    gaps = [math.hypot(o["x"] - ROCK_XY[0], o["y"] - ROCK_XY[1]) for o in seen]
    assert seen and statistics.median(gaps) < ROCK_RADIUS_M + 0.2
    ring = json.loads(read_metadata(result.mcap_path)["scenario"]["perception_json"])
    assert [s["yaw_deg"] for s in ring["rangefinders"]] == [0.0, -30.0, 30.0, -100.0, 100.0]
