"""Rover-config values that contradict each other across keys: one ConfigError naming both keys and values."""

from __future__ import annotations

import pytest

from logs.settings import ConfigError, parse_toml
from navigator.config import RoverConfig, rover_config_from_table

SMALL_MAP = '[map]\nkind = "procedural"\nsize_m = [10.0, 10.0]\nresolution_m = 0.5\n'


def load(text: str) -> RoverConfig:
    return rover_config_from_table(parse_toml(text, "rover.toml"))


@pytest.mark.parametrize(
    ("text", "key", "named"),
    [
        (
            "[vehicle]\nmax_wheel_speed_mps = 1.5\n[follower]\nmax_speed_mps = 2.0\n",
            "follower.max_speed_mps",
            ("2 m/s", "vehicle.max_wheel_speed_mps 1.5 m/s"),
        ),
        (
            SMALL_MAP + "[follower]\nlookahead_m = 0.3\n",
            "follower.lookahead_m",
            ("0.3 m", "map.resolution_m 0.5 m"),
        ),
        (
            "[safety]\nstuck_min_command_mps = 0.2\nstuck_max_speed_mps = 0.3\n",
            "safety.stuck_max_speed_mps",
            ("0.3 m/s", "safety.stuck_min_command_mps 0.2 m/s"),
        ),
        (
            "[follower]\nmax_speed_mps = 0.5\n[safety]\nstuck_min_command_mps = 0.8\n",
            "safety.stuck_min_command_mps",
            ("0.8 m/s", "follower.max_speed_mps 0.5 m/s", "stuck_time_s = 0"),
        ),
        (
            "[follower]\nmax_speed_mps = 0.4\n",  # the default back-off speed, 0.5 m/s, is faster
            "planner.yield_speed_mps",
            ("0.5 m/s", "follower.max_speed_mps 0.4 m/s"),
        ),
        (
            "[vehicle]\ntrack_m = 0.8\nfootprint_width_m = 0.7\n",
            "vehicle.footprint_width_m",
            ("0.7 m", "track_m 0.8 m"),
        ),
        (
            "[vehicle]\nwheelbase_m = 1.0\nfootprint_length_m = 0.9\n",
            "vehicle.footprint_length_m",
            ("0.9 m", "wheelbase_m 1 m"),
        ),
    ],
)
def test_contradicting_values_name_both_keys(text: str, key: str, named: tuple[str, ...]) -> None:
    with pytest.raises(ConfigError) as caught:
        load(text)
    assert caught.value.source == "rover.toml"
    assert caught.value.key == key
    for words in named:
        assert words in caught.value.problem


@pytest.mark.parametrize(
    "text",
    [
        "",  # the shipped defaults
        "[vehicle]\nmax_wheel_speed_mps = 1.5\n[follower]\nmax_speed_mps = 1.5\n",  # at the limit
        SMALL_MAP + "[follower]\nlookahead_m = 0.5\n",  # one cell
        "[follower]\nlookahead_m = 0.1\n",  # no [map]: no cell size to compare with
        # The stuck check turned off: its speeds are not used, so they cannot contradict anything.
        "[follower]\nmax_speed_mps = 0.5\n[safety]\nstuck_time_s = 0.0\nstuck_min_command_mps = 0.8\n",
        "[safety]\nstuck_time_s = 0.0\nstuck_min_command_mps = 0.2\nstuck_max_speed_mps = 0.3\n",
        # a slow rover backs off slower
        "[follower]\nmax_speed_mps = 0.4\n[planner]\nyield_speed_mps = 0.3\n",
    ],
)
def test_consistent_values_load(text: str) -> None:
    load(text)


@pytest.mark.parametrize(
    ("key", "vehicle_value", "estimator_value"), [("track_m", 0.5, 0.6), ("skid_factor", 1.5, 1.8)]
)
def test_estimator_kinematics_are_set_in_vehicle_only(
    key: str, vehicle_value: float, estimator_value: float
) -> None:
    # The estimator takes them from [vehicle]; one given in [estimator] used to be read and then silently
    # replaced, so a user's edit there did nothing.
    with pytest.raises(ConfigError) as caught:
        load(f"[vehicle]\n{key} = {vehicle_value}\n[estimator]\n{key} = {estimator_value}\n")
    assert caught.value.key == f"estimator.{key}"
    assert f"[vehicle] {key}" in caught.value.problem


@pytest.mark.parametrize(
    ("text", "key", "named"),
    [
        ("[vehicle]\nwheel_radius_m = 110\n", "vehicle.wheel_radius_m", ("110 m", "metres", "0.11")),
        (
            "[vehicle]\ntrack_m = 550\nwheelbase_m = 700\n"
            "footprint_length_m = 900\nfootprint_width_m = 700\n",
            "vehicle.wheelbase_m",
            ("700 m", "metres"),
        ),
        # A diameter, or centimetres with the rest in metres: the wheels of a side would overlap.
        (
            "[vehicle]\nwheel_radius_m = 0.22\n",
            "vehicle.wheel_radius_m",
            ("wheelbase_m 0.7 m / 4", "overlap"),
        ),
        ("[vehicle]\nwheel_radius_m = 1.1\n", "vehicle.wheel_radius_m", ("1.1 m", "overlap", "diameter")),
    ],
)
def test_vehicle_lengths_in_the_wrong_unit_are_refused(text: str, key: str, named: tuple[str, ...]) -> None:
    with pytest.raises(ConfigError) as caught:
        load(text)
    assert caught.value.key == key
    for words in named:
        assert words in caught.value.problem, caught.value.problem


def test_the_shipped_vehicle_loads() -> None:
    vehicle = load("").vehicle
    assert vehicle.wheel_radius_m <= vehicle.wheelbase_m / 4


@pytest.mark.parametrize(
    ("fence", "key", "named"),
    [
        # Points on one line: nothing is inside, so the rover is always outside and every goal refused.
        ("[[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]]", "safety.fence", ("enclose no area",)),
        # A bow tie: the points out of order around the square, two edges cross.
        (
            "[[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]]",
            "safety.fence",
            ("edge [0.0, 0.0] -> [10.0, 10.0] meets edge [10.0, 0.0] -> [0.0, 10.0]", "in order"),
        ),
        # Negative ENU metres, as if relative to the start: wholly off a map at [0, 10) x [0, 10).
        (
            "[[-1.0, -1.0], [-10.0, -1.0], [-10.0, -10.0], [-1.0, -10.0]]",
            "safety.fence",
            ("lies wholly off the map", "x [0, 10) and y [0, 10)"),
        ),
        # A key held down: an integer too large for a float (TOML reads any length) is no coordinate.
        (f"[[0.0, 0.0], [5.0, 0.0], [{'9' * 400}, 5.0]]", "safety.fence", ("expected a list of [x, y]",)),
    ],
)
def test_a_fence_that_cannot_be_meant_is_refused(fence: str, key: str, named: tuple[str, ...]) -> None:
    with pytest.raises(ConfigError) as caught:
        load(SMALL_MAP + f"[safety]\nfence = {fence}\n")
    assert caught.value.key == key
    for words in named:
        assert words in caught.value.problem, caught.value.problem


@pytest.mark.parametrize(
    "fence",
    [
        "[[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]",  # the map's own edge
        "[[-5.0, -5.0], [5.0, -5.0], [5.0, 5.0], [-5.0, 5.0]]",  # partly off the map
        "[[0.0, 0.0], [0.0, 10.0], [10.0, 10.0], [10.0, 0.0]]",  # clockwise
        "[[0.0, 0.0], [8.0, 0.0], [8.0, 8.0], [4.0, 3.0], [0.0, 8.0]]",  # concave
        "[[-20.0, -20.0], [30.0, -20.0], [30.0, 30.0], [-20.0, 30.0]]",  # round the whole map
    ],
)
def test_fences_a_person_means_load(fence: str) -> None:
    assert load(SMALL_MAP + f"[safety]\nfence = {fence}\n").safety.fence


def test_the_back_off_settings_are_read_and_checked_in_range() -> None:
    planner = load(
        "[planner]\nyield_speed_mps = 0.3\nyield_margin_m = 0.5\nyield_max_m = 2.0\nyield_max_s = 6.0\n"
    )
    assert (planner.planner.yield_speed_mps, planner.planner.yield_margin_m) == (0.3, 0.5)
    assert (planner.planner.yield_max_m, planner.planner.yield_max_s) == (2.0, 6.0)
    with pytest.raises(ConfigError) as caught:
        load("[planner]\nyield_max_m = -1.0\n")
    assert caught.value.key == "planner.yield_max_m"


def test_the_recovery_settings_are_read_and_checked() -> None:
    planner = load(
        "[planner]\nrecover_when_stuck = false\nrecovery_back_m = 2.5\nrecovery_attempts = 3\n"
    ).planner
    assert (planner.recover_when_stuck, planner.recovery_back_m, planner.recovery_attempts) == (False, 2.5, 3)
    for text, key in [
        ('recover_when_stuck = "yes"', "planner.recover_when_stuck"),
        ("recovery_back_m = 0.2", "planner.recovery_back_m"),  # the mark would lie under the rover
        ("recovery_attempts = 0", "planner.recovery_attempts"),  # that is recover_when_stuck = false
        ("recovery_attempts = 1.5", "planner.recovery_attempts"),
    ]:
        with pytest.raises(ConfigError) as caught:
            load(f"[planner]\n{text}\n")
        assert caught.value.key == key
