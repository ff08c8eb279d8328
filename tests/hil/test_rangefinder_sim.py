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
from hil.rangefinder_sim import MIN_RANGE_M, SimRangefinders, mavlink_orientation, yaw_ring
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
    wide, _ = _ring(beside, sensors=yaw_ring([0]), fov_deg=30.0)
    narrow, _ = _ring(beside, sensors=yaw_ring([0]), fov_deg=0.0)
    (reading,) = wide.ranges(0, 0.0, 0.0, 0.0)
    assert reading is not None and 3.7 < reading < math.hypot(4.0, 1.0)
    assert narrow.ranges(0, 0.0, 0.0, 0.0) == [None]


def test_the_ring_sits_where_its_mount_says() -> None:
    ring, _ = _ring([ROCK], sensors=yaw_ring([0, 90], SensorMount(forward_m=0.4, left_m=0.2)))
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
        ({"sensors": ()}, "at least one sensor"),
        ({"fov_deg": 120.0}, "fov_deg"),
        ({"range_m": 0.1}, "range_m"),
        ({"rate_hz": 0.0}, "rate_hz"),
        ({"noise_m": float("nan")}, "noise_m"),
    ],
)
def test_a_ring_it_cannot_simulate_is_refused(kwargs: dict[str, Any], named: str) -> None:
    with pytest.raises(ValueError, match=named):
        _ring([], **kwargs)


@pytest.mark.parametrize(
    ("yaw_deg", "named"), [([10], "multiples of 45"), ([0, 0], "twice"), ([], "multiples")]
)
def test_a_ring_of_45_degree_steps_it_cannot_build_is_refused(yaw_deg: list[int], named: str) -> None:
    with pytest.raises(ValueError, match=named):
        yaw_ring(yaw_deg)


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


def test_each_sensor_sits_and_faces_where_its_own_mount_says() -> None:
    # A corner sensor 0.5 m forward, 0.3 m left, turned 30 degrees left; a rock 3 m further along its axis.
    corner = SensorMount(forward_m=0.5, left_m=0.3, yaw_rad=math.radians(30.0))
    along = (0.5 + 3.5 * math.cos(math.radians(30.0)), 0.3 + 3.5 * math.sin(math.radians(30.0)))
    rock = ("rock", along[0], along[1], 0.5, 0.0, 0.0)
    ring, sent = _ring([rock], sensors=(SensorMount(), corner), fov_deg=0.0)
    assert ring.ranges(0, 0.0, 0.0, 0.0) == [None, pytest.approx(3.0)]
    ring.step(0.0, 0.0, 0.0)
    front, turned = (read_beam(msg, 0) for msg in sent)
    assert sent[1].orientation == mavlink2.MAV_SENSOR_ROTATION_CUSTOM
    assert turned is not None and turned.bearing_rad == pytest.approx(math.radians(30.0))
    assert turned.range_m == pytest.approx(3.0, abs=0.01)
    assert front is not None and front.range_m is None


def test_a_sensor_on_a_45_degree_step_says_so_by_name_and_others_by_quaternion() -> None:
    assert mavlink_orientation(-math.radians(90.0)) == (mavlink2.MAV_SENSOR_ROTATION_YAW_90, (0.0,) * 4)
    assert mavlink_orientation(math.radians(45.0))[0] == mavlink2.MAV_SENSOR_ROTATION_YAW_315
    assert mavlink_orientation(math.pi)[0] == mavlink2.MAV_SENSOR_ROTATION_YAW_180
    orientation, (w, x, y, z) = mavlink_orientation(math.radians(10.0))  # 10 degrees left: yaw 350 in FRD
    assert orientation == mavlink2.MAV_SENSOR_ROTATION_CUSTOM and (x, y) == (0.0, 0.0)
    assert 2.0 * math.degrees(math.atan2(z, w)) == pytest.approx(350.0)


def test_the_scenario_places_each_sensor_and_refuses_a_bad_ring(tmp_path: Path) -> None:
    sensors = _scenario_with(
        'perception = "rangefinders"\nperception_mount_forward_m = 0.2\n'
        "rangefinders = [{yaw_deg = 0.0, forward_m = 0.45}, {yaw_deg = 30.0, left_m = 0.25},"
        " {yaw_deg = 270.0}]"
    ).sensors
    # Counter-clockwise, as perception_mount_yaw_deg: 30 turns the sensor left; 270 is 90 to the right.
    assert sensors.rangefinder_ring == (
        SensorMount(0.45, 0.0, 0.0),
        SensorMount(0.2, 0.25, math.radians(30.0)),
        SensorMount(0.2, 0.0, math.radians(-90.0)),
    )
    for bad, key in [
        ("rangefinders = []", "rangefinders"),
        ("rangefinders = [{yaw_deg = 0.0}]\nrangefinder_yaw_deg = [0]", "rangefinders"),
        ("rangefinders = [{forward_m = 0.1}]", "yaw_deg"),
        ("rangefinders = [{yaw_deg = 0.0, forward_m = 9.0}]", "forward_m"),
        ("rangefinders = [{yaw_deg = 0.0, up_m = 0.1}]", "up_m"),
        ("rangefinders = [{yaw_deg = 400.0}]", "yaw_deg"),
        ("rangefinders = [{yaw_deg = 10.0}, {yaw_deg = -350.0}]", "sensor 1 is sensor 0 again"),
        ("rangefinders = [{yaw_deg = 180.0}, {yaw_deg = -180.0}]", "sensor 1 is sensor 0 again"),
    ]:
        with pytest.raises(ConfigError, match=key):
            _scenario_with(f'perception = "rangefinders"\n{bad}')
    scenario = _scenario_with(
        'perception = "rangefinders"\nrangefinders = [{yaw_deg = 20.0, forward_m = 0.4, left_m = -0.1}]'
    )
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    written = load_rover_config(write_peer_files(tmp_path, scenario, config, mavlink_port=14550))
    assert [(m.sensor_id, m.forward_m, m.left_m) for m in written.perception.rangefinders] == [(0, 0.4, -0.1)]
