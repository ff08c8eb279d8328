"""Guidance: plan, repair after new obstacles (same cost as a fresh plan), stop for moving obstacles,
and follow straight lines and arcs within cross-track bounds with either controller."""

import math

import numpy as np
import pytest

from logs.settings import ConfigError, parse_toml
from navigator.config import PlannerConfig, rover_config_from_table
from navigator.errors import ParameterError
from navigator.follower import FollowerConfig, PurePursuit
from navigator.guidance import ARRIVED, BLOCKED, DRIVING, IDLE, NO_PATH, Guidance
from navigator.perception import ObstacleObservation
from navigator.planner import Planner
from navigator.stanley import Stanley
from navigator.terrain import TerrainMap, disc_mask
from navigator.vehicle import VehicleParams, stability_margins

PARAMS = VehicleParams()


def _flat(rows: int = 80, cols: int = 120, res: float = 0.25) -> TerrainMap:
    return TerrainMap(
        np.zeros((rows, cols)), np.zeros((rows, cols), np.uint8), np.zeros((rows, cols), bool), res
    )


def _guidance(terrain: TerrainMap, sensing_range_m: float = 40.0) -> Guidance:
    return Guidance(terrain, PARAMS, PlannerConfig(sensing_range_m=sensing_range_m), FollowerConfig())


def test_idle_then_plans_and_drives() -> None:
    guidance = _guidance(_flat())
    assert guidance.update(0, 2.0, 10.0, 0.0, 0.0).mode == IDLE
    guidance.set_goal(27.0, 10.0)
    out = guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    assert out.mode == DRIVING and out.path_changed and out.path is not None and out.speed_mps > 0.0
    assert not guidance.update(1, 2.0, 10.0, 0.0, 0.0).path_changed


def test_repair_after_a_new_obstacle_costs_the_same_as_a_fresh_plan() -> None:
    terrain = _flat()
    guidance = _guidance(terrain)
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    # An obstacle off the path: the plan is kept (still optimal), no replan.
    guidance.observe([ObstacleObservation(0, "aside", 6.0, 14.0, 0.5)])
    out = guidance.update(1, 2.0, 10.0, 0.0, 0.0)
    assert not out.path_changed and guidance.repairs_kept == 1
    # An obstacle on the path: repaired, and the repaired cost equals a fresh plan on the updated map.
    guidance.observe([ObstacleObservation(2, "rock", 14.0, 10.0, 1.0)])
    out = guidance.update(2, 2.0, 10.0, 0.0, 0.0)
    assert out.path_changed and out.path is not None and "block" in out.detail
    updated = terrain.with_obstacles(disc_mask(terrain, 6.0, 14.0, 0.5) | disc_mask(terrain, 14.0, 10.0, 1.0))
    fresh = Planner(updated, PARAMS).plan((2.0, 10.0), (27.0, 10.0))
    assert out.path.cost == pytest.approx(fresh.cost, rel=1e-12)
    kept_cost = Planner(terrain.with_obstacles(disc_mask(terrain, 6.0, 14.0, 0.5)), PARAMS).plan(
        (2.0, 10.0), (27.0, 10.0)
    )
    assert kept_cost.cost == pytest.approx(Planner(terrain, PARAMS).plan((2.0, 10.0), (27.0, 10.0)).cost)


def test_far_obstacles_wait_until_in_sensing_range_and_bad_ones_are_rejected() -> None:
    guidance = _guidance(_flat(), sensing_range_m=8.0)
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    guidance.observe(
        [ObstacleObservation(0, "far", 20.0, 10.0, 0.5), ObstacleObservation(0, "bad", math.nan, 1, 1)]
    )
    assert not guidance.update(1, 2.0, 10.0, 0.0, 0.0).path_changed  # 18 m away, range 8 m
    assert guidance.update(2, 13.0, 10.0, 0.0, 0.5).path_changed  # now within range: replanned


def test_walled_off_goal_is_no_path() -> None:
    guidance = _guidance(_flat())
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    guidance.observe([ObstacleObservation(0, "wall", 27.0, 10.0, 3.0)])
    out = guidance.update(1, 2.0, 10.0, 0.0, 0.0)
    assert out.mode == NO_PATH and out.speed_mps == 0.0 and "lethal" in out.detail


def test_moving_obstacle_crossing_ahead_stops_the_rover_then_it_goes_on() -> None:
    guidance = _guidance(_flat())
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    # A walker 3 m ahead, 2 m to the side, walking across the path at 1 m/s.
    guidance.observe([ObstacleObservation(0, "walker", 5.0, 12.0, 0.3, vx=0.0, vy=-1.0)])
    out = guidance.update(0, 2.0, 10.0, 0.0, 0.5)
    assert out.mode == BLOCKED and out.speed_mps == 0.0 and out.speed_limit_reason == "moving_obstacle"
    # Seen again having crossed and walking away: the way is clear, and once it has stayed clear for
    # moving_clear_s (0.5 s) the rover drives on.
    guidance.observe([ObstacleObservation(4_000_000_000, "walker", 5.0, 6.0, 0.3, vx=0.0, vy=-1.0)])
    assert guidance.update(4_000_000_000, 2.0, 10.0, 0.0, 0.0).mode == BLOCKED
    assert guidance.update(4_500_000_000, 2.0, 10.0, 0.0, 0.0).mode == DRIVING


def test_blocked_is_reported_when_it_starts_and_ends_not_on_every_tick() -> None:
    guidance = _guidance(_flat())
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    # A cart 3 m ahead standing across the path (moving, 0.01 m/s): blocked for as long as it stands.
    guidance.observe([ObstacleObservation(0, "cart", 5.0, 10.0, 0.5, vx=0.0, vy=-0.01)])
    ticks = [guidance.update(i * 20_000_000, 2.0, 10.0, 0.0, 0.0) for i in range(50)]
    assert all(out.mode == BLOCKED for out in ticks)
    details = [out.detail for out in ticks if out.detail]
    assert details == ["moving obstacle cart predicted on the path"]
    assert guidance.blocker == "cart"
    # It moves away: still BLOCKED until the way has been clear for 0.5 s (25 ticks), then one "way clear"
    # on the tick the mode goes back to DRIVING, then silence.
    guidance.observe([ObstacleObservation(1_000_000_000, "cart", 5.0, 20.0, 0.5, vx=0.0, vy=1.0)])
    after = [guidance.update(1_000_000_000 + i * 20_000_000, 2.0, 10.0, 0.0, 0.0) for i in range(30)]
    assert [out.mode for out in after] == [BLOCKED] * 25 + [DRIVING] * 5
    assert [out.detail for out in after if out.detail] == [
        "way clear: moving obstacle cart no longer on the path"
    ]
    assert after[25].detail and guidance.blocker is None


def test_blocked_stays_blocked_when_stopping_shrinks_the_corridor_it_judges() -> None:
    guidance = _guidance(_flat())
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    # A cart standing on the path 5 m ahead: within the corridor at 1 m/s (3 s x 1 m/s + lookahead), not
    # within the 3 m one at standstill.
    guidance.observe([ObstacleObservation(0, "cart", 7.0, 10.0, 0.3, vx=0.0, vy=-0.01)])
    assert guidance.update(20_000_000, 2.0, 10.0, 0.0, 1.0).mode == BLOCKED
    # Stopped for it: still in the way of the speed it would drive at, so still BLOCKED (it once went
    # DRIVING here, sped up, and was BLOCKED again: a flicker every few ticks).
    stopped = [guidance.update(40_000_000 + i * 20_000_000, 2.0, 10.0, 0.0, 0.0) for i in range(20)]
    assert all(out.mode == BLOCKED for out in stopped)
    # Gone: clear (for 0.5 s), and judged at the speed of the moment again.
    guidance.observe([ObstacleObservation(1_000_000_000, "cart", 7.0, 20.0, 0.3, vx=0.0, vy=1.0)])
    guidance.update(1_000_000_000, 2.0, 10.0, 0.0, 0.0)
    assert guidance.update(1_500_000_000, 2.0, 10.0, 0.0, 0.0).mode == DRIVING


def test_a_way_clear_for_less_than_moving_clear_s_does_not_end_the_wait() -> None:
    guidance = _guidance(_flat())
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    guidance.observe([ObstacleObservation(0, "cart", 5.0, 10.0, 0.5, vx=0.0, vy=-0.01)])
    assert guidance.update(20_000_000, 2.0, 10.0, 0.0, 0.0).mode == BLOCKED
    details: list[str] = []

    def tick(t_ns: int, cart_y: float) -> str:
        guidance.observe([ObstacleObservation(t_ns, "cart", 5.0, cart_y, 0.5, vx=0.0, vy=-0.01)])
        out = guidance.update(t_ns, 2.0, 10.0, 0.0, 0.0)
        details.extend([out.detail] if out.detail else [])
        return out.mode

    # The cart seems off the path for 0.4 s (a jumpy estimate, a turn at the end of its track), then back
    # on it: the wait goes on, with no event; the clear time starts again from zero.
    modes = [tick(40_000_000 + i * 20_000_000, 20.0) for i in range(20)]
    modes += [tick(440_000_000 + i * 20_000_000, 10.0) for i in range(5)]
    assert modes == [BLOCKED] * 25 and details == []
    # Off the path for good: BLOCKED for 0.5 s of clear, then DRIVING, with one "way clear".
    start_ns = 540_000_000
    modes = [tick(start_ns + i * 20_000_000, 20.0) for i in range(30)]
    first_driving = modes.index(DRIVING)
    assert modes[first_driving:] == [DRIVING] * (30 - first_driving)
    assert first_driving * 20_000_000 == PlannerConfig().moving_clear_s * 1e9
    assert details == ["way clear: moving obstacle cart no longer on the path"]


def test_moving_clear_s_zero_leaves_blocked_on_the_first_clear_tick() -> None:
    guidance = Guidance(_flat(), PARAMS, PlannerConfig(moving_clear_s=0.0), FollowerConfig())
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    guidance.observe([ObstacleObservation(0, "cart", 5.0, 10.0, 0.5, vx=0.0, vy=-0.01)])
    assert guidance.update(20_000_000, 2.0, 10.0, 0.0, 0.0).mode == BLOCKED
    guidance.observe([ObstacleObservation(40_000_000, "cart", 5.0, 20.0, 0.5, vx=0.0, vy=1.0)])
    assert guidance.update(40_000_000, 2.0, 10.0, 0.0, 0.0).mode == DRIVING


@pytest.mark.parametrize(("forget_s", "blocked_at_4s"), [(2.0, False), (0.0, True)])
def test_a_moving_obstacle_unseen_for_moving_forget_s_is_no_longer_predicted(
    forget_s: float, blocked_at_4s: bool
) -> None:
    guidance = Guidance(_flat(), PARAMS, PlannerConfig(moving_forget_s=forget_s), FollowerConfig())
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    # Seen once, standing across the path, then never again (out of view, or a lidar track forgotten).
    guidance.observe([ObstacleObservation(0, "cart", 5.0, 10.0, 0.5, vx=0.0, vy=-0.01)])
    modes = {t_s: guidance.update(round(t_s * 1e9), 2.0, 10.0, 0.0, 0.0).mode for t_s in (0.02, 1.9)}
    assert modes == {0.02: BLOCKED, 1.9: BLOCKED}
    later = [guidance.update(round((2.0 + 0.02 * i) * 1e9), 2.0, 10.0, 0.0, 0.0).mode for i in range(100)]
    assert (later[-1] == BLOCKED) is blocked_at_4s
    if not blocked_at_4s:
        # Forgotten after 2 s, then the way must stay clear for moving_clear_s before it drives on.
        assert later.index(DRIVING) * 0.02 == pytest.approx(PlannerConfig().moving_clear_s, abs=0.03)


def test_moving_forget_s_is_read_and_checked() -> None:
    config = rover_config_from_table(parse_toml("[planner]\nmoving_forget_s = 5.0\n", "<t>"))
    assert config.planner.moving_forget_s == 5.0
    with pytest.raises(ConfigError, match="moving_forget_s"):
        rover_config_from_table(parse_toml("[planner]\nmoving_forget_s = -1.0\n", "<t>"))


def _drive(
    follower: PurePursuit, path: np.ndarray, pose: tuple[float, float, float], steps: int
) -> list[float]:
    """Kinematic unicycle at 20 Hz; returns |cross-track error| per step."""
    x, y, yaw = pose
    speed = 0.0
    errors = []
    for _ in range(steps):
        cmd = follower.command(x, y, yaw, speed, path)
        errors.append(abs(cmd.cross_track_error_m))
        if cmd.arrived:
            break
        speed = cmd.speed_mps
        yaw += cmd.yaw_rate_rps * 0.05
        x += speed * math.cos(yaw) * 0.05
        y += speed * math.sin(yaw) * 0.05
    return errors


@pytest.mark.parametrize("controller", [PurePursuit, Stanley])
def test_cross_track_error_bounds_on_a_line_and_an_arc(controller: type[PurePursuit]) -> None:
    config = FollowerConfig(controller="stanley" if controller is Stanley else "pure_pursuit")
    line = np.column_stack([np.linspace(0.0, 20.0, 81), np.zeros(81)])
    errors = _drive(controller(config), line, (0.0, 0.5, 0.0), 600)
    assert max(errors[len(errors) // 2 :]) < 0.05  # converged onto the line
    assert max(errors) <= 0.55  # never further off than it started (+ a little overshoot)
    angles = np.linspace(-math.pi / 2, math.pi / 2, 120)
    arc = np.column_stack([5.0 * np.cos(angles), 5.0 * np.sin(angles) + 5.0])  # radius 5 m
    errors = _drive(controller(config), arc, (0.0, 0.0, 0.0), 800)
    assert max(errors) < 0.25


def test_arrives_and_stays_arrived() -> None:
    guidance = _guidance(_flat())
    guidance.set_goal(5.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    out = guidance.update(1, 4.9, 10.0, 0.0, 0.2)
    assert out.mode == ARRIVED and out.arrived
    assert guidance.update(2, 4.9, 10.0, 0.0, 0.0).mode == ARRIVED


@pytest.mark.parametrize("yaw", [0.0, -0.4])  # across the slope (roll only); diagonal (roll and pitch)
def test_side_slope_turn_is_slowed_to_the_tip_margin_the_simulator_judges(yaw: float) -> None:
    rows, cols, res = 80, 120, 0.25
    grade = math.tan(math.radians(30.0))
    elevation = np.tile((np.arange(rows) * res * grade)[:, None], (1, cols))  # rises to the north
    terrain = TerrainMap(elevation, np.zeros((rows, cols), np.uint8), np.zeros((rows, cols), bool), res)
    follower = FollowerConfig(max_speed_mps=2.0)
    guidance = Guidance(terrain, PARAMS, PlannerConfig(cost_mode="classical"), follower)
    guidance.set_goal(20.0, 12.0)
    out = guidance.update(0, 5.0, 5.0, yaw, 1.0)  # the goal up-left: a turn on the slope
    assert out.speed_limit_reason == "tip_margin"
    assert out.speed_limit_mps < 2.0
    # The turn's v * omega (= v^2 kappa) tilts the specific force to the tip angle less the margin kept.
    ground = terrain.ground_on_map(5.0, 5.0, yaw)
    assert ground is not None
    lateral = out.speed_mps * abs(out.yaw_rate_rps)
    margin, _ = stability_margins(
        PARAMS, ground.roll_rad, ground.pitch_rad, lateral_accel_mps2=math.copysign(lateral, ground.roll_rad)
    )
    assert margin == pytest.approx(follower.min_tip_margin_rad, abs=1e-9)


def test_a_far_obstacle_seen_every_cycle_waits_once_and_enters_the_map_at_its_newest_sighting() -> None:
    # Perception reports an obstacle every cycle while in view; beyond sensing range it waits for the rover,
    # and a long wait must not pile up one entry per sighting (memory, per-tick work, repeated ids in logs).
    guidance = _guidance(_flat(), sensing_range_m=5.0)
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    for k in range(600):  # a minute at 10 Hz, the last sighting a little further east
        guidance.observe([ObstacleObservation(k, "rock", 14.0 + (0.2 if k == 599 else 0.0), 10.0, 1.0)])
        guidance.update(k, 2.0, 10.0, 0.0, 0.0)
    out = guidance.update(600, 11.0, 10.0, 0.0, 0.0)  # now within 5 m
    assert out.path_changed and out.detail.count("rock") == 1
    assert guidance.planner.cost_grid[guidance.planner.terrain.cell_of(14.2 + 0.9, 10.0)] == np.inf


def test_moving_clear_s_is_read_from_the_planner_table_and_checked() -> None:
    config = rover_config_from_table(parse_toml("[planner]\nmoving_clear_s = 1.5\n", "<test>"))
    assert config.planner.moving_clear_s == 1.5
    with pytest.raises(ConfigError, match=r"planner\.moving_clear_s"):
        rover_config_from_table(parse_toml("[planner]\nmoving_clear_s = -0.1\n", "<test>"))


def test_footprint_inflation_is_read_from_the_planner_table_and_guidance_plans_with_it() -> None:
    # A 1.1 m corridor: the circumscribed circle (the default) blocks it, the inscribed one lets the rover
    # through lengthwise (tests/navigator/test_planner_footprint.py); the config now chooses, as for
    # `rover plan --config`.
    walls = np.ones((40, 80), dtype=bool)
    walls[16:27, :] = False
    corridor = TerrainMap(np.zeros(walls.shape), np.zeros(walls.shape, np.uint8), walls, 0.1)
    outcomes = {}
    for text in ("", 'footprint_inflation = "inscribed"\n'):
        config = rover_config_from_table(parse_toml(f'[planner]\ncost_mode = "classical"\n{text}', "<test>"))
        guidance = Guidance(corridor, PARAMS, config.planner, FollowerConfig())
        guidance.set_goal(7.0, 2.15)
        outcomes[config.planner.footprint_inflation] = guidance.update(0, 1.0, 2.15, 0.0, 0.0).mode
    assert outcomes == {"circumscribed": NO_PATH, "inscribed": DRIVING}
    with pytest.raises(ConfigError, match=r"planner\.footprint_inflation"):
        rover_config_from_table(parse_toml('[planner]\nfootprint_inflation = "square"\n', "<test>"))


def test_an_obstacle_seen_standing_then_moving_is_taken_off_the_map_and_the_way_replanned() -> None:
    # A cart waiting to start is reported at zero speed: a static obstacle, put in the map. Once it is seen
    # moving it must leave the map (before, it stayed there for good: a phantom the plan kept avoiding),
    # while an obstacle that never moved stays.
    terrain = _flat()
    guidance = _guidance(terrain)
    guidance.set_goal(27.0, 10.0)
    direct = guidance.update(0, 2.0, 10.0, 0.0, 0.0).path
    assert direct is not None
    guidance.observe(
        [ObstacleObservation(1, "cart", 14.0, 10.0, 1.0), ObstacleObservation(1, "rock", 20.0, 16.0, 0.5)]
    )
    around = guidance.update(1, 2.0, 10.0, 0.0, 0.0)
    assert around.path_changed and around.path is not None and around.path.cost > direct.cost
    cart_cell = guidance.planner.terrain.cell_of(14.0, 10.0)
    rock_cell = guidance.planner.terrain.cell_of(20.0, 16.0)
    assert guidance.planner.terrain.obstacles[cart_cell] and guidance.planner.terrain.obstacles[rock_cell]
    guidance.observe([ObstacleObservation(2, "cart", 14.0, 25.0, 1.0, vx=0.0, vy=1.0)])  # off, far north
    moved = guidance.update(2, 2.0, 10.0, 0.0, 0.0)
    assert "cart moved on: taken off the map" in moved.detail
    assert not guidance.planner.terrain.obstacles[cart_cell]  # the cart's cells are free again
    assert guidance.planner.terrain.obstacles[rock_cell]  # the rock never moved
    assert moved.path_changed and moved.path is not None
    # The new plan is the one a fresh planner makes on the map with the rock alone.
    with_rock = terrain.with_obstacles(disc_mask(terrain, 20.0, 16.0, 0.5))
    fresh = Planner(with_rock, PARAMS).plan((2.0, 10.0), (27.0, 10.0))
    assert moved.path.cost == pytest.approx(fresh.cost, rel=1e-12)
    # Nothing more to do on the next tick: the removal was done once.
    assert not guidance.update(3, 2.0, 10.0, 0.0, 0.0).path_changed


def test_an_obstacle_pending_static_that_starts_moving_never_enters_the_map() -> None:
    guidance = _guidance(_flat(), sensing_range_m=5.0)
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    guidance.observe([ObstacleObservation(1, "cart", 14.0, 10.0, 1.0)])  # standing, out of range: pending
    guidance.update(1, 2.0, 10.0, 0.0, 0.0)
    guidance.observe([ObstacleObservation(2, "cart", 14.0, 25.0, 1.0, vx=0.0, vy=1.0)])  # it drove off
    out = guidance.update(3, 11.0, 10.0, 0.0, 0.0)  # the rover is now within 5 m of where it stood
    assert "cart" not in out.detail
    assert not guidance.planner.terrain.obstacles[guidance.planner.terrain.cell_of(14.0, 10.0)]


def test_a_mission_speed_limit_lowers_the_target_speed_and_never_raises_it() -> None:
    guidance = _guidance(_flat())
    guidance.set_goal(27.0, 10.0)  # straight east: the follower's own limit is max_speed (1 m/s)
    out = guidance.update(0, 2.0, 10.0, 0.0, 1.0)
    assert (out.speed_mps, out.speed_limit_reason) == (1.0, "max_speed")
    guidance.limit_speed(0.4)
    out = guidance.update(1, 2.0, 10.0, 0.0, 1.0)
    assert (out.speed_mps, out.speed_limit_mps, out.speed_limit_reason) == (0.4, 0.4, "mission_speed")
    guidance.limit_speed(3.0)  # above the rover's top speed: the follower's limit stands
    out = guidance.update(2, 2.0, 10.0, 0.0, 1.0)
    assert (out.speed_mps, out.speed_limit_reason) == (1.0, "max_speed")
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ParameterError, match="speed limit"):
            guidance.limit_speed(bad)
    assert guidance.mission_speed_mps == 3.0  # the limit in force kept
    guidance.limit_speed(None)
    assert guidance.mission_speed_mps is None


def test_a_smaller_limit_of_another_kind_still_wins_over_the_mission_speed() -> None:
    guidance = _guidance(_flat())
    guidance.set_goal(3.5, 10.0)  # 1.5 m ahead: the goal approach limits to ~1.0 x 1.5 / 2 m/s
    guidance.limit_speed(0.9)
    out = guidance.update(0, 2.0, 10.0, 0.0, 0.5)
    assert out.speed_limit_reason == "goal_approach" and out.speed_mps < 0.85
    guidance.limit_speed(0.5)
    out = guidance.update(1, 2.0, 10.0, 0.0, 0.5)
    assert (out.speed_mps, out.speed_limit_reason) == (0.5, "mission_speed")
