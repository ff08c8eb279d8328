import math

import numpy as np
import pytest

from logs.settings import ConfigError, parse_toml
from navigator.errors import ParameterError
from navigator.follower import FollowerConfig, PurePursuit
from navigator.stanley import Stanley


def drive(follower, path, x, y, yaw, seconds, dt=0.05):
    """A trivial kinematic rover that does exactly what it is told (unicycle)."""
    speed = 0.0
    history = []
    for _ in range(round(seconds / dt)):
        cmd = follower.command(x, y, yaw, speed, path)
        history.append((x, y, yaw, cmd))
        if cmd.arrived:
            break
        speed = cmd.speed_mps
        yaw += cmd.yaw_rate_rps * dt
        x += speed * math.cos(yaw) * dt
        y += speed * math.sin(yaw) * dt
    return history


def test_converges_onto_a_straight_line_from_an_offset():
    path = np.array([[0.0, 0.0], [10.0, 0.0], [25.0, 0.0]])
    follower = PurePursuit(FollowerConfig())
    history = drive(follower, path, 0.0, 1.5, 0.0, seconds=40.0)
    errors = [cmd.cross_track_error_m for *_, cmd in history]
    assert errors[0] == pytest.approx(1.5)  # left of the path is positive
    assert max(abs(e) for e in errors) <= 1.5 + 1e-9  # bounded: never further off than at the start
    assert min(errors) > -0.2  # little overshoot to the other side
    late = [abs(e) for (x, *_, cmd), e in zip(history, errors, strict=True) if x > 8.0]
    assert max(late) < 0.05
    assert history[-1][3].arrived
    assert math.hypot(history[-1][0] - 25.0, history[-1][1]) <= FollowerConfig().goal_tolerance_m
    assert all(abs(cmd.yaw_rate_rps) <= 1.2 + 1e-9 for *_, cmd in history)


def test_right_of_path_is_negative_and_limits_are_named():
    path = np.array([[0.0, 0.0], [20.0, 0.0]])
    gentle = FollowerConfig(max_lateral_accel_mps2=0.3)
    cmd = PurePursuit(gentle).command(5.0, -0.5, 0.0, 0.5, path)
    assert cmd.cross_track_error_m == pytest.approx(-0.5)
    assert cmd.yaw_rate_rps > 0.0  # steer left, back to the path
    assert cmd.speed_limit_reason == "curvature"
    curvature = cmd.yaw_rate_rps / cmd.speed_mps
    assert cmd.speed_mps == pytest.approx(math.sqrt(0.3 / curvature))
    straight = PurePursuit(FollowerConfig()).command(5.0, 0.0, 0.0, 0.5, path)
    assert straight.speed_limit_reason == "max_speed" and straight.speed_mps == pytest.approx(1.0)
    near_end = PurePursuit(FollowerConfig()).command(19.0, 0.0, 0.0, 0.5, path)
    assert near_end.speed_limit_reason == "goal_approach" and near_end.speed_mps == pytest.approx(0.5)


def test_turns_in_place_when_the_path_is_behind():
    path = np.array([[0.0, 0.0], [-10.0, 0.0]])
    cmd = PurePursuit(FollowerConfig()).command(0.0, 0.0, 0.0, 0.0, path)
    assert cmd.speed_mps == 0.0 and cmd.speed_limit_reason == "turn_in_place"
    assert abs(cmd.yaw_rate_rps) == pytest.approx(1.2)


def test_progress_never_jumps_back_on_a_hairpin():
    # Out east along y=0, back west along y=1.0: the return leg passes close to the start.
    path = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 1.0], [0.0, 1.0]])
    follower = PurePursuit(FollowerConfig(lookahead_m=0.8, lookahead_gain_s=0.0))
    for x in np.arange(0.0, 10.0, 0.5):
        follower.command(float(x), 0.0, 0.0, 0.5, path)
    for x in np.arange(10.0, 1.0, -0.5):
        follower.command(float(x), 1.0, math.pi, 0.5, path)
    # Back near the start: the out leg (y=0) is 0.4 m away, the return leg 0.6 m; it keeps the return leg.
    cmd = follower.command(1.0, 0.4, math.pi, 0.5, path)
    assert cmd.cross_track_error_m == pytest.approx(0.6)  # measured from the return leg (left of it)
    assert cmd.yaw_rate_rps < 0.0 or cmd.speed_limit_reason == "turn_in_place"


def test_a_new_path_starts_over_and_bad_paths_are_rejected():
    follower = PurePursuit(FollowerConfig())
    first = np.array([[0.0, 0.0], [10.0, 0.0]])
    for x in range(10):
        follower.command(float(x), 0.0, 0.0, 1.0, first)
    second = np.array([[0.0, 5.0], [10.0, 5.0]])
    cmd = follower.command(0.0, 4.0, 0.0, 0.0, second)
    assert cmd.cross_track_error_m == pytest.approx(-1.0)
    with pytest.raises(ParameterError):
        follower.command(0.0, 0.0, 0.0, 0.0, np.zeros((3, 3)))
    with pytest.raises(ParameterError):
        follower.command(math.nan, 0.0, 0.0, 0.0, first)


def test_config_from_table():
    cfg = FollowerConfig.from_table(parse_toml("lookahead_m = 2.0\nmax_speed_mps = 0.8\n", "rover.toml"))
    assert cfg.lookahead_m == 2.0 and cfg.max_speed_mps == 0.8 and cfg.goal_tolerance_m == 0.5
    with pytest.raises(ConfigError, match="look_ahead"):
        FollowerConfig.from_table(parse_toml("look_ahead = 2.0\n", "rover.toml"))
    with pytest.raises(ConfigError, match="max_speed_mps"):
        FollowerConfig.from_table(parse_toml("max_speed_mps = 0\n", "rover.toml"))
    with pytest.raises(ConfigError, match="goal_settle_m"):
        FollowerConfig.from_table(parse_toml("goal_tolerance_m = 0.3\ngoal_settle_m = 0.4\n", "rover.toml"))


def test_inside_the_tolerance_it_creeps_on_to_the_settle_radius():
    """Stopping at the tolerance's edge would leave the true stop at the edge plus the estimate's error."""
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    cfg = FollowerConfig()
    history = drive(PurePursuit(cfg), path, 0.0, 0.0, 0.0, seconds=40.0, dt=0.02)
    assert history[-1][3].arrived
    first_inside = next(i for i, (x, y, *_) in enumerate(history) if math.hypot(x - 10.0, y) <= 0.5)
    assert not history[first_inside][3].arrived  # inside the tolerance, not yet arrived
    final = math.hypot(history[-1][0] - 10.0, history[-1][1])
    assert final <= cfg.goal_settle_m
    assert final > cfg.goal_settle_m - 0.02 * cfg.max_speed_mps  # stopped on the tick it got there


def test_a_goal_passed_beside_it_inside_the_tolerance_is_arrived_at_without_circling():
    # The path ends at (10, 0); the rover runs parallel 0.3 m to its left and cannot get within 0.15 m
    # without turning back: it arrives as the distance grows again (or the goal falls abeam).
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    follower = PurePursuit(FollowerConfig())
    x, closest, arrived_at = 8.0, math.inf, None
    for _ in range(400):
        distance = math.hypot(x - 10.0, 0.3)
        closest = min(closest, distance)
        cmd = follower.command(x, 0.3, 0.0, 0.2, path)
        if cmd.arrived:
            arrived_at = x
            break
        x += 0.01  # keeps going straight whatever it is told: the estimate slides past the goal
    assert arrived_at is not None and 9.6 <= arrived_at <= 10.5  # 9.6: where the tolerance begins
    assert math.hypot(arrived_at - 10.0, 0.3) <= FollowerConfig().goal_tolerance_m


@pytest.mark.parametrize("follower_class", [PurePursuit, Stanley])
def test_a_rover_that_stops_moving_inside_the_tolerance_has_arrived(follower_class):
    """Stuck 0.3 m short (mud, a seized wheel): creeping on forever would never arrive, and the creep is
    too slow for the stuck failsafe."""
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    follower = follower_class(FollowerConfig())
    moving = follower.command(9.7, 0.0, 0.0, 0.12, path)
    assert not moving.arrived and moving.speed_mps > 0.0  # still creeping on while it moves
    assert follower.command(9.7, 0.0, 0.0, 0.0, path).arrived


def _read_only(points: np.ndarray) -> np.ndarray:
    frozen = np.array(points, dtype=np.float64)
    frozen.flags.writeable = False
    return frozen


@pytest.mark.parametrize("follower_class", [PurePursuit, Stanley])
def test_a_read_only_path_known_by_identity_commands_as_a_path_compared_every_tick(follower_class):
    """The fast path (a read-only path handed in again is not checked again) gives the same commands,
    to the bit, as a writable path that is compared point by point on every tick."""
    points = np.array([[0.0, 0.0], [4.0, 0.5], [8.0, 3.0], [9.0, 7.0], [6.0, 10.0], [2.0, 11.0]])
    frozen = _read_only(points)
    fast, slow = follower_class(FollowerConfig()), follower_class(FollowerConfig())
    fast_run = drive(fast, frozen, 0.3, -0.4, 0.2, seconds=60.0)
    slow_run = drive(slow, points, 0.3, -0.4, 0.2, seconds=60.0)
    assert fast_run == slow_run
    assert fast_run[-1][3].arrived


def test_a_writable_path_changed_in_place_is_adopted_anew():
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    follower = PurePursuit(FollowerConfig())
    follower.command(2.0, 0.0, 0.0, 0.5, path)
    path[:, 1] = 5.0  # the same array object, other points: it must not be taken for the old path
    assert follower.command(2.0, 4.0, 0.0, 0.5, path).cross_track_error_m == pytest.approx(-1.0)


def test_a_new_read_only_path_and_a_reset_start_over():
    first, second = _read_only([[0.0, 0.0], [10.0, 0.0]]), _read_only([[0.0, 5.0], [10.0, 5.0]])
    follower = PurePursuit(FollowerConfig())
    for x in range(8):
        follower.command(float(x), 0.0, 0.0, 1.0, first)
    assert follower.command(0.0, 4.0, 0.0, 0.0, second).cross_track_error_m == pytest.approx(-1.0)
    follower.reset()
    assert follower.command(0.0, 1.0, 0.0, 0.0, first).cross_track_error_m == pytest.approx(1.0)
