"""Perception through a lidar's scans (``[sensors] perception = "scan"``), the way ``rover run`` perceives.

The simulated lidar sends OBSTACLE_DISTANCE over MAVLink; the onboard stack tracks obstacles from those
scans alone (no obstacle objects handed over). A rock missing from the rover's map, on the straight line
to the goal, is found, tracked and driven around. The HIL peer always perceives this way: it has no
other channel to ``rover run``.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from hil.lockstep import lockstep_wires
from hil.peer import seen_through_lidar
from hil.scenario import load_scenario, with_perception
from hil.trial import run_trial
from logs import topics
from logs.clock import NS_PER_S
from logs.reader import read_messages, read_metadata
from logs.settings import parse_toml
from navigator.config import rover_config_from_table
from tests.hil.world_harness import StepClock, run_peer_on_test_clock

DATA = Path(__file__).resolve().parents[1] / "data"
ROCK_XY, ROCK_RADIUS_M = (7.0, 5.0), 0.6


def _config():
    return rover_config_from_table(parse_toml("", "<defaults>"))


def test_the_rock_on_the_straight_line_is_what_the_rover_must_find() -> None:
    scenario = load_scenario(DATA / "hidden_rock.toml")
    (rock,) = scenario.obstacles
    assert not rock.known and (rock.x, rock.y) == ROCK_XY
    # The straight line start -> goal runs through it: without perception the rover would hit it.
    (sx, sy), goal = scenario.start_xy, scenario.goals[-1]
    t = np.linspace(0.0, 1.0, 200)
    gaps = np.hypot(sx + t * (goal.x - sx) - rock.x, sy + t * (goal.y - sy) - rock.y)
    assert gaps.min() < rock.radius_m


def test_a_lockstep_trial_finds_the_hidden_rock_through_scans_alone(tmp_path: Path) -> None:
    result = run_trial(load_scenario(DATA / "hidden_rock.toml"), _config(), tmp_path / "trial")
    assert result.metrics.goal_reached and result.metrics.collisions == 0, result.metrics
    seen = [
        obstacle
        for message in read_messages(result.mcap_path, topics={topics.PERCEPTION_OBSTACLES})
        for obstacle in message.message["obstacles"]
    ]
    # Only tracks of its own: no "hidden-rock" object came to the stack.
    assert seen and all(o["id"].startswith("scan-") for o in seen)
    near = [o for o in seen if math.hypot(o["x"] - ROCK_XY[0], o["y"] - ROCK_XY[1]) < 0.5]
    # Static throughout: tracked on the fused pose it seemed to move for 2 s while the estimate settled
    # (GPS noise 0.5 m); in the dead-reckoned frame it does not (docs/planning.md "Perception from scans").
    assert len(near) > len(seen) / 2 and all(o["vx"] == 0.0 and o["vy"] == 0.0 for o in near)
    scans = [
        m
        for m in read_messages(result.mcap_path, topics={topics.MAVLINK_RAW})
        if m.message["direction"] == "rx" and m.message["msgid"] == mavlink2.MAVLINK_MSG_ID_OBSTACLE_DISTANCE
    ]
    assert len(scans) >= 10 * 15  # 10 Hz over a drive of more than 15 s, each recorded as it came
    scenario_record = read_metadata(result.mcap_path)["scenario"]
    assert scenario_record["perception"] == "scan"
    assert json.loads(scenario_record["perception_json"])["fov_deg"] == 360.0


def test_a_scan_trial_is_deterministic_and_noise_shows_in_the_scans(tmp_path: Path) -> None:
    scenario = load_scenario(DATA / "hidden_rock.toml")
    noisy = dataclasses.replace(
        scenario, sensors=dataclasses.replace(scenario.sensors, perception_noise_m=0.05)
    )
    runs = [run_trial(noisy, _config(), tmp_path / name) for name in ("a", "b")]
    first, second = ([(m.topic, m.log_time_ns, m.message) for m in read_messages(r.mcap_path)] for r in runs)
    assert first == second
    quiet = run_trial(scenario, _config(), tmp_path / "quiet")

    def scan_bytes(path: Path) -> list[str]:
        return [
            m.message["data"]
            for m in read_messages(path, topics={topics.MAVLINK_RAW})
            if m.message["msgid"] == mavlink2.MAVLINK_MSG_ID_OBSTACLE_DISTANCE
        ][:20]

    assert scan_bytes(runs[0].mcap_path) != scan_bytes(quiet.mcap_path)  # the noise reaches the wire


def test_the_peer_sends_scans_whatever_its_scenario_says(tmp_path: Path) -> None:
    scenario = with_perception(load_scenario(DATA / "hidden_rock.toml"), "objects")
    assert seen_through_lidar(scenario).sensors.perception == "scan"
    config = _config()
    with lockstep_wires(config.can) as wires:
        run_peer_on_test_clock(
            scenario, config, tmp_path / "peer", StepClock(), wires.sim_bus, wires.sim_mavlink,
            duration_ns=NS_PER_S // 2,
        )  # fmt: skip
        received = wires.onboard_mavlink.read()
    # The truth says how the rover perceived, not what the scenario file asked for.
    assert read_metadata(tmp_path / "peer" / "truth.mcap")["scenario"]["perception"] == "scan"
    messages = mavlink2.MAVLink(None).parse_buffer(received) or []
    scans = [m for m in messages if m.get_type() == "OBSTACLE_DISTANCE"]
    assert len(scans) >= 4  # 10 Hz for half a second
    # The rock 5 m straight ahead: the front sector reads its near edge, 4.4 m.
    assert scans[-1].frame == mavlink2.MAV_FRAME_BODY_FRD
    assert abs(scans[-1].distances[0] - 440) <= 5
