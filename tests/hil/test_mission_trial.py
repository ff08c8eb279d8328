"""A lockstep trial in which a ground station uploads a 3-waypoint mission over MAVLink (the rover's
ground-station link): the onboard stack drives it in order to the end, in place of the scenario's own
goals, and the recording says what was uploaded and reached; one with a MAV_CMD_DO_CHANGE_SPEED between
two legs, the second driven at or below its speed."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pymap3d
import pytest
from pymavlink.dialects.v20 import common as mavlink2

from hil.scenario import load_scenario
from hil.trial import run_trial
from logs import topics
from logs.reader import read_messages
from logs.settings import parse_toml
from navigator.config import rover_config_from_table
from tests.firmware_bridge.ground_station import (
    ScriptedGroundStation,
    change_speed,
    return_to_launch,
    waypoint,
)

DATA = Path(__file__).resolve().parents[1] / "data"
# ENU metres on small_rocky's map (14 x 10 m, the rock at (6.5, 4.5)): not the scenario's own goals.
UPLOADED = [(3.0, 8.0), (9.0, 8.0), (12.0, 3.0)]


def test_a_mission_uploaded_over_mavlink_is_driven_in_order_to_the_end(tmp_path: Path) -> None:
    scenario = load_scenario(DATA / "small_rocky_waypoints.toml")
    assert [(g.x, g.y) for g in scenario.goals] != UPLOADED
    items = [
        waypoint(seq, *pymap3d.enu2geodetic(x, y, 0.0, *scenario.datum)[:2])
        for seq, (x, y) in enumerate(UPLOADED)
    ]
    station = ScriptedGroundStation(items)
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    result = run_trial(scenario, config, tmp_path / "trial", ground_station=station)

    assert result.end_reason == "arrived", result
    (ack,) = station.station.of_type("MISSION_ACK")
    assert ack.type == mavlink2.MAV_MISSION_ACCEPTED
    assert [m.seq for m in station.station.of_type("MISSION_ITEM_REACHED")] == [0, 1, 2]

    events = [m.message for m in read_messages(result.mcap_path, topics=[topics.SAFETY_EVENTS])]
    kinds = [e["kind"] for e in events]
    missions = [e["detail"] for e in events if e["kind"] == "mission"]
    assert missions[0].startswith("mission of 3 waypoints from scenario small-rocky-waypoints")
    assert missions[1].startswith(
        "mission of 3 waypoints from MAVLink upload by 255/190 on the ground_station"
    )
    reached = [e["detail"] for e in events if e["kind"] == "mission_item_reached"]
    assert [r.split(" (")[0] for r in reached] == ["item 0 of 3", "item 1 of 3", "item 2 of 3"]
    # The uploaded mission replaced the scenario's before the rover moved: none of its items was reached.
    assert kinds.index("mission_item_reached") > kinds.index("mission", kinds.index("mission") + 1)
    assert kinds[-1] == "mission_complete"

    # The ground-station link's own count of the upload.
    stats = [
        m.message
        for m in read_messages(result.mcap_path, topics=[topics.MAVLINK_STATS])
        if m.message["link"] == "ground_station"
    ]
    assert sum(s.get("missions_accepted", 0) for s in stats) == 1
    assert sum(s.get("mission_refused", 0) for s in stats) == 0

    # Where the rover stopped: the last uploaded waypoint, by the truth.
    final = [
        m.message["pose"]["position"] for m in read_messages(result.mcap_path, topics=[topics.TRUTH_POSE])
    ][-1]
    assert math.hypot(final["x"] - UPLOADED[-1][0], final["y"] - UPLOADED[-1][1]) < 0.6
    # ... having passed the others in order.
    poses = [
        (m.message["pose"]["position"]["x"], m.message["pose"]["position"]["y"])
        for m in read_messages(result.mcap_path, topics=[topics.TRUTH_POSE])
    ]
    closest = [nearest(poses, w) for w in UPLOADED]
    assert closest == sorted(closest)
    assert all(math.dist(poses[i], w) < 0.6 for i, w in zip(closest, UPLOADED, strict=True))


# Two legs on small_rocky's map from the start (2, 2), clear of the rock: a long one at full speed, then a
# DO_CHANGE_SPEED to 0.5 m/s, then the second leg.
FAST_LEG, SLOW_LEG, SLOW_MPS = (7.0, 2.0), (10.0, 4.5), 0.5


def test_the_legs_after_a_speed_change_are_driven_at_or_below_its_speed(tmp_path: Path) -> None:
    scenario = load_scenario(DATA / "small_rocky_waypoints.toml")
    place = [pymap3d.enu2geodetic(x, y, 0.0, *scenario.datum)[:2] for x, y in (FAST_LEG, SLOW_LEG)]
    station = ScriptedGroundStation(
        [waypoint(0, *place[0]), change_speed(1, SLOW_MPS), waypoint(2, *place[1])]
    )
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    result = run_trial(scenario, config, tmp_path / "trial", ground_station=station)

    assert result.end_reason == "arrived", result
    assert [m.seq for m in station.station.of_type("MISSION_ITEM_REACHED")] == [0, 1, 2]
    events = list(read_messages(result.mcap_path, topics=[topics.SAFETY_EVENTS]))
    speeds = [(m.log_time_ns, m.message["detail"]) for m in events if m.message["kind"] == "mission_speed"]
    assert [detail for _, detail in speeds] == [
        "item 1 of 3: mission speed limit 0.50 m/s",
        "mission speed limit 0.50 m/s lifted: the mission is complete",
    ]
    applied_ns, lifted_ns = (t for t, _ in speeds)

    def during(topic: str, start_ns: int, end_ns: int) -> list[dict[str, Any]]:
        return [
            m.message
            for m in read_messages(result.mcap_path, topics=[topic])
            if start_ns <= m.log_time_ns < end_ns
        ]

    # The leg before: faster than the limit (rocky ground allows 1 / sqrt(1.6) = 0.79 m/s), by guidance's
    # target and by the truth.
    before = during(topics.NAVIGATOR_STATE, 0, applied_ns)
    assert max(s["target_speed_mps"] for s in before) > SLOW_MPS + 0.2
    assert max(p["speed_mps"] for p in during(topics.TRUTH_POSE, 0, applied_ns)) > SLOW_MPS + 0.2
    # The leg after: at or below it; navigator/state names the mission's limit while it holds the rover back.
    after = during(topics.NAVIGATOR_STATE, applied_ns, lifted_ns)
    assert max(s["target_speed_mps"] for s in after) <= SLOW_MPS
    assert max(p["speed_mps"] for p in during(topics.TRUTH_POSE, applied_ns, lifted_ns)) <= SLOW_MPS + 0.02
    assert {s["speed_limit_reason"] for s in after} >= {"mission_speed"}
    assert max(s["speed_limit_mps"] for s in after if s["speed_limit_reason"] == "mission_speed") == SLOW_MPS
    final = during(topics.TRUTH_POSE, lifted_ns, lifted_ns + 1)[-1]["pose"]["position"]
    assert math.hypot(final["x"] - SLOW_LEG[0], final["y"] - SLOW_LEG[1]) < 0.6


def test_a_mission_ending_in_return_to_launch_brings_the_rover_home(tmp_path: Path) -> None:
    scenario = load_scenario(DATA / "small_rocky_waypoints.toml")
    away = pymap3d.enu2geodetic(*FAST_LEG, 0.0, *scenario.datum)[:2]
    station = ScriptedGroundStation([waypoint(0, *away), return_to_launch(1)])
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    result = run_trial(scenario, config, tmp_path / "trial", ground_station=station)

    assert result.end_reason == "arrived", result
    assert [m.seq for m in station.station.of_type("MISSION_ITEM_REACHED")] == [0, 1]
    events = [m.message for m in read_messages(result.mcap_path, topics=[topics.SAFETY_EVENTS])]
    # The recording says where home was: the first healthy estimate of where it stood (the start, within GPS
    # noise).
    (home,) = [e["detail"] for e in events if e["kind"] == "home"]
    x, y = map(float, home.split("ENU (")[1].split(",")[:2])
    assert math.dist((x, y), scenario.start_xy) < 1.0, home
    assert [e["detail"] for e in events if e["kind"] == "mission_complete"] == [
        "mission complete: returned to launch at item 1: the rover holds at home"
    ]
    poses = [
        m.message["pose"]["position"] for m in read_messages(result.mcap_path, topics=[topics.TRUTH_POSE])
    ]
    assert min(math.dist((p["x"], p["y"]), FAST_LEG) for p in poses) < 0.6  # it went out
    assert math.dist((poses[-1]["x"], poses[-1]["y"]), (x, y)) < 0.6  # and came back home


def nearest(poses: list[tuple[float, float]], point: tuple[float, float]) -> int:
    return min(range(len(poses)), key=lambda i: math.dist(poses[i], point))


@pytest.mark.parametrize("scenario_file", ["small_rocky.toml", "small_rocky_waypoints.toml"])
def test_the_scenarios_goals_are_the_onboard_mission(scenario_file: str, tmp_path: Path) -> None:
    scenario = load_scenario(DATA / scenario_file)
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    result = run_trial(scenario, config, tmp_path / "trial")
    assert result.end_reason == "arrived"
    events = [m.message for m in read_messages(result.mcap_path, topics=[topics.SAFETY_EVENTS])]
    assert [e["kind"] for e in events if e["kind"].startswith("mission")] == [
        "mission",
        *["mission_item_reached"] * len(scenario.goals),
        "mission_complete",
    ]
    states = [m.message for m in read_messages(result.mcap_path, topics=[topics.NAVIGATOR_STATE])]
    assert states[-1]["mission"] == {
        "state": "COMPLETE",
        "current": len(scenario.goals) - 1,
        "count": len(scenario.goals),
    }


def test_a_scenario_goal_the_stack_refuses_ends_the_trial_failed_at_once(tmp_path: Path) -> None:
    """A goal outside the geofence: the onboard stack refuses the mission (``mission_rejected``); the trial
    ends there, failed, naming why, instead of idling to its timeout."""
    scenario = load_scenario(DATA / "small_rocky.toml")  # start (2, 2), goal (11.5, 7.5)
    fence = "[safety]\nfence = [[0.0, 0.0], [8.0, 0.0], [8.0, 10.0], [0.0, 10.0]]\n"
    config = rover_config_from_table(parse_toml(fence, "<fence>"))
    result = run_trial(scenario, config, tmp_path / "trial")
    assert result.end_reason == "mission_rejected" and not result.success
    assert any(
        f.startswith("mission rejected: the onboard stack refused the scenario's") for f in result.failures
    )
    assert result.simulated_s == 0.0
    events = [m.message for m in read_messages(result.mcap_path, topics=[topics.SAFETY_EVENTS])]
    assert [e["detail"] for e in events if e["kind"] == "mission_rejected"] == [
        "mission from scenario small-rocky: waypoint 0 (11.50, 7.50) is outside the geofence"
    ]
    logged = [m.message["message"] for m in read_messages(result.mcap_path, topics=[topics.LOG])]
    assert any(line.startswith("mission rejected:") for line in logged)
