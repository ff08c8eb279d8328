"""The simulated ring of rangefinders: each reads the nearest obstacle edge within its cone, and the
simulated autopilot sends the readings as DISTANCE_SENSOR; the scenario keys that set the ring."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.distance_sensor import read_beam
from firmware_bridge.mavlink_transport import memory_pipe_pair
from hil.autopilot_sim import SimAutopilot
from hil.peer import seen_through_lidar
from hil.peer_files import write_peer_files
from hil.rangefinder_sim import MIN_RANGE_M, SimRangefinders
from hil.scenario import PERCEPTION_MODELS, Scenario, load_scenario, scenario_from_table, with_perception
from logs.clock import SimClock
from logs.settings import ConfigError, parse_toml
from navigator.config import load_rover_config, rover_config_from_table
from navigator.sensor_mount import SensorMount

DATA = Path(__file__).resolve().parents[1] / "data"
ROCK = ("rock", 4.0, 0.0, 0.5, 0.0, 0.0)


def _ring(discs: list[Any], **kwargs: Any) -> tuple[SimRangefinders, list[Any]]:
    sent: list[Any] = []
    ring = SimRangefinders(sent.append, SimClock(0), lambda _t: discs, np.random.default_rng(0), **kwargs)
    return ring, sent


def test_the_front_sensor_reads_the_near_edge_and_the_others_nothing() -> None:
    ring, _ = _ring([ROCK])
    # Default ring: front, front-right, front-left, right, left.
    assert ring.ranges(0, 0.0, 0.0, 0.0) == [pytest.approx(3.5), None, None, None, None]
    # Turned a quarter to the left, the rock lies to the right: sensor 3 (90 deg clockwise) reads it.
    assert ring.ranges(0, 0.0, 0.0, math.pi / 2) == [None, None, None, pytest.approx(3.5), None]


def test_a_cone_reads_an_edge_off_its_axis_and_a_beam_does_not() -> None:
    # A rock 4 m ahead and 1 m to the left: 14 deg off the axis, its near edge 10 deg off.
    beside = [("rock", 4.0, 1.0, 0.3, 0.0, 0.0)]
    wide, _ = _ring(beside, yaw_deg=[0], fov_deg=30.0)
    narrow, _ = _ring(beside, yaw_deg=[0], fov_deg=0.0)
    (reading,) = wide.ranges(0, 0.0, 0.0, 0.0)
    assert reading is not None and 3.7 < reading < math.hypot(4.0, 1.0)
    assert narrow.ranges(0, 0.0, 0.0, 0.0) == [None]


def test_the_ring_sits_where_its_mount_says() -> None:
    ring, _ = _ring([ROCK], mount=SensorMount(forward_m=0.4, left_m=0.2))
    assert ring.ranges(0, 0.0, 0.0, 0.0)[0] == pytest.approx(math.hypot(4.0 - 0.4, 0.2) - 0.5, abs=0.01)


def test_each_reading_goes_out_from_the_autopilot_as_distance_sensor() -> None:
    rover_end, sim_end = memory_pipe_pair()
    clock = SimClock(0)
    autopilot = SimAutopilot(
        sim_end, clock, np.random.default_rng(0), datum_lat_deg=47.0, datum_lon_deg=8.0, datum_alt_m=400.0
    )
    ring = SimRangefinders(
        autopilot.send_sensor, clock, lambda _t: [ROCK], np.random.default_rng(0), fov_deg=20.0
    )
    ring.step(0.0, 0.0, 0.0)
    ring.step(0.0, 0.0, 0.0)  # not due again yet: 10 Hz
    messages = mavlink2.MAVLink(None).parse_buffer(rover_end.read()) or []
    assert [m.get_type() for m in messages] == ["DISTANCE_SENSOR"] * 5
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in messages} == {(1, 1)}
    assert [m.id for m in messages] == [0, 1, 2, 3, 4]
    assert [m.orientation for m in messages] == [0, 1, 7, 2, 6]
    assert messages[0].current_distance == 350 and messages[1].current_distance == 801  # nothing: max + 1
    assert messages[0].horizontal_fov == pytest.approx(math.radians(20.0))
    assert messages[0].min_distance == round(MIN_RANGE_M * 100)
    beams = [read_beam(m, 0) for m in messages]
    assert [b.range_m if b else "refused" for b in beams] == [3.5, None, None, None, None]
    assert autopilot.sent["DISTANCE_SENSOR"] == 5


def test_the_noise_is_the_seeds() -> None:
    a = _ring([ROCK], noise_m=0.05)[0].ranges(0, 0.0, 0.0, 0.0)
    b = _ring([ROCK], noise_m=0.05)[0].ranges(0, 0.0, 0.0, 0.0)
    assert a == b and a[0] != pytest.approx(3.5, abs=1e-6)


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"yaw_deg": [10]}, "multiples of 45"),
        ({"yaw_deg": [0, 0]}, "twice"),
        ({"yaw_deg": []}, "multiples of 45"),
        ({"fov_deg": 120.0}, "fov_deg"),
        ({"range_m": 0.1}, "range_m"),
        ({"rate_hz": 0.0}, "rate_hz"),
        ({"noise_m": float("nan")}, "noise_m"),
    ],
)
def test_a_ring_it_cannot_simulate_is_refused(kwargs: dict[str, Any], named: str) -> None:
    with pytest.raises(ValueError, match=named):
        _ring([], **kwargs)


def _scenario_with(sensors: str) -> Scenario:
    """``tests/data/hidden_rock.toml`` with ``sensors`` in place of its ``perception = "scan"``."""
    text = (DATA / "hidden_rock.toml").read_text().replace('perception = "scan"', sensors)
    return scenario_from_table(parse_toml(text, "<scenario>"), text, base_dir=DATA)


def test_the_scenario_sets_the_ring_and_refuses_a_bad_one() -> None:
    assert "rangefinders" in PERCEPTION_MODELS
    sensors = _scenario_with(
        'perception = "rangefinders"\nrangefinder_yaw_deg = [0, 180]\nrangefinder_fov_deg = 25.0'
    ).sensors
    assert (sensors.perception, sensors.rangefinder_yaw_deg, sensors.rangefinder_fov_deg) == (
        "rangefinders",
        (0, 180),
        25.0,
    )
    for bad, key in [
        ("rangefinder_yaw_deg = [0, 30]", "rangefinder_yaw_deg"),
        ("rangefinder_yaw_deg = [0, 0]", "rangefinder_yaw_deg"),
        ("rangefinder_yaw_deg = [0, 45, 90, 135, 180, 225, 270, 315, 0]", "rangefinder_yaw_deg"),
        ("rangefinder_fov_deg = 91.0", "rangefinder_fov_deg"),
        ("perception_mount_yaw_deg = 90.0", "perception_mount_yaw_deg"),
    ]:
        with pytest.raises(ConfigError, match=key):
            _scenario_with(f'perception = "rangefinders"\n{bad}')


def test_the_peer_keeps_rangefinders_and_tells_rover_run_where_they_sit(tmp_path: Path) -> None:
    scenario = _scenario_with(
        'perception = "rangefinders"\nperception_mount_forward_m = 0.3\nrangefinder_yaw_deg = [0, 90]'
    )
    assert seen_through_lidar(scenario).sensors.perception == "rangefinders"
    assert seen_through_lidar(with_perception(scenario, "objects")).sensors.perception == "scan"
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    written = load_rover_config(write_peer_files(tmp_path, scenario, config, mavlink_port=14550))
    assert [(m.sensor_id, m.forward_m, m.left_m) for m in written.perception.rangefinders] == [
        (0, 0.3, 0.0),
        (1, 0.3, 0.0),
    ]
    assert load_scenario(DATA / "hidden_rock.toml").sensors.perception == "scan"
