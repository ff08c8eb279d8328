import math

import numpy as np
import pytest

from hil.dynamics import DynamicsError, RoverDynamics, check_wheel_speeds
from hil.traction import slip_for_ratio
from navigator.follower import FollowerConfig, PurePursuit
from navigator.footprint import Footprint, footprint_collides
from navigator.mixing import mix_skid_steer
from navigator.planner import Planner
from navigator.terrain import TerrainMap, from_maze
from navigator.terrain_classes import TERRAIN_CLASSES, TerrainClass
from navigator.vehicle import G, VehicleParams, max_climbable_slope_rad

PARAMS = VehicleParams()
DT = 0.01
VOLTS = 24.0
MAZE = [[1, 1, 1, 1, 1, 1], [1, 2, 2, 1, 1, 1], [1, 2, 1, 1, 1, 1], [1, 2, 1, 2, 2, 1], [1, 1, 1, 2, 1, 1]]


def plane(grade_x=0.0, grade_y=0.0, size=(80, 80), res=0.25, class_id=0, obstacles=None):
    rows, cols = size
    xs = (np.arange(cols) + 0.5) * res
    ys = (np.arange(rows) + 0.5) * res
    elevation = grade_x * xs[np.newaxis, :] + grade_y * ys[:, np.newaxis]
    return TerrainMap(
        elevation,
        np.full(size, class_id, np.uint8),
        np.zeros(size, bool) if obstacles is None else obstacles,
        res,
    )


def run(body, wheels, seconds):
    return [body.step(DT, wheels, VOLTS) for _ in range(round(seconds / DT))]


def test_drives_straight_and_turns_at_the_skid_steer_rate_less_the_slip():
    firm = TERRAIN_CLASSES[0]
    body = RoverDynamics(plane(), PARAMS, x=5.0, y=10.0, yaw=0.0)
    steps = run(body, [1.0] * 6, 3.0)
    # Rolling resistance needs a pull of crr N per wheel: the ground lags the tyres by the curve's slip.
    rolling_slip = slip_for_ratio(firm.rolling_resistance, firm.friction_mu, firm.slip_constant)
    assert 0.0 < rolling_slip < 0.01
    assert body.speed == pytest.approx(1.0 - rolling_slip, rel=1e-6)
    assert body.x > 7.0 and body.y == pytest.approx(10.0)
    assert steps[-1].specific_force_body_mps2 == pytest.approx((0.0, 0.0, G), abs=1e-3)
    body = RoverDynamics(plane(), PARAMS, x=10.0, y=10.0, yaw=0.0)
    run(body, [-0.4] * 3 + [0.4] * 3, 2.0)
    # On firm ground a turn on the spot slips a little (closed form in test_traction_physics.py).
    assert 0.9 * 0.8 / PARAMS.effective_track_m < body.yaw_rate < 0.8 / PARAMS.effective_track_m
    assert body.speed == pytest.approx(0.0, abs=1e-9)


def test_locked_wheels_slide_down_at_the_papers_rate():
    theta = math.radians(20.0)
    mu = 0.1
    ice = {0: TerrainClass(0, "ice", mu, 0.02, 1.0, "test")}
    body = RoverDynamics(
        plane(grade_x=math.tan(theta)), PARAMS, ice, x=10.0, y=10.0, yaw=0.0
    )  # facing uphill
    steps = run(body, [0.0] * 6, 0.6)
    accel = (steps[-1].speed_mps - steps[9].speed_mps) / ((len(steps) - 10) * DT)
    expected = G * (math.sin(theta) - mu * math.cos(theta))
    assert accel == pytest.approx(-expected, rel=1e-6)  # backwards, down the slope
    assert body.x < 10.0
    # The same slope with grippy ground holds the rover still.
    held = RoverDynamics(plane(grade_x=math.tan(theta)), PARAMS, x=10.0, y=10.0, yaw=0.0)
    run(held, [0.0] * 6, 1.0)
    assert held.x == pytest.approx(10.0) and held.speed == pytest.approx(0.0)


def test_cannot_climb_past_tan_mu_minus_crr():
    firm = TERRAIN_CLASSES[0]
    limit = max_climbable_slope_rad(firm.friction_mu, firm.rolling_resistance)
    too_steep = RoverDynamics(plane(grade_x=math.tan(limit) + 0.04), PARAMS, x=10.0, y=10.0, yaw=0.0)
    steps = run(too_steep, [1.0] * 6, 3.0)
    assert too_steep.x < 10.0  # wheels spin, it slides back
    assert max(s.slip[0] for s in steps[-10:]) == pytest.approx(1.0)
    climbable = RoverDynamics(plane(grade_x=math.tan(limit) - 0.06), PARAMS, x=10.0, y=10.0, yaw=0.0)
    run(climbable, [1.0] * 6, 3.0)
    assert climbable.x > 10.5
    assert climbable.pitch == pytest.approx(math.atan(math.tan(limit) - 0.06))


def test_normal_forces_and_currents_on_a_slope():
    theta = math.radians(15.0)
    body = RoverDynamics(plane(grade_x=math.tan(theta)), PARAMS, x=10.0, y=10.0, yaw=0.0)
    steps = run(body, [0.5] * 6, 2.0)
    last = steps[-1]
    assert sum(last.normal_forces_n) == pytest.approx(PARAMS.mass_kg * G * math.cos(theta), rel=1e-9)
    assert last.normal_forces_n[2] > last.normal_forces_n[0]  # rear wheels carry more uphill
    # Steady climb: traction balances gravity and rolling resistance.
    crr = TERRAIN_CLASSES[0].rolling_resistance
    expected_drive = PARAMS.mass_kg * G * (math.sin(theta) + crr * math.cos(theta))
    assert sum(last.traction_forces_n) == pytest.approx(expected_drive, rel=1e-3)
    assert all(c > 0.0 for c in last.motor_currents_a)
    assert all(0.0 < d < 1.0 for d in last.duty)
    assert last.energy_wh > 0.0 and last.specific_force_body_mps2[0] == pytest.approx(
        G * math.sin(theta), rel=1e-3
    )


@pytest.mark.parametrize(("degrees", "tips"), [(45.0, True), (40.0, False)])
def test_static_tilt_and_rollover(degrees, tips):
    assert math.degrees(PARAMS.tip_roll_rad) == pytest.approx(42.5, abs=0.1)
    # Heading east across a slope that rises to the north (the rover's left): roll = slope angle. On ground
    # grippy enough to hold it there (mu 1.2: atan 50 deg); on firm ground (mu 0.8) it slides sideways
    # before it tips (tests/hil/test_sideways_slide.py).
    grippy = {0: TerrainClass(0, "grippy", 1.2, 0.02, 1.0, "test")}
    body = RoverDynamics(
        plane(grade_y=math.tan(math.radians(degrees))), PARAMS, grippy, x=10.0, y=10.0, yaw=0.0
    )
    steps = run(body, [0.0] * 6, 0.2)
    assert body.roll == pytest.approx(math.radians(degrees))
    assert steps[-1].rollover is tips
    assert sum(s.rollover_started for s in steps) == (1 if tips else 0)
    if tips:
        run(body, [1.0] * 6, 1.0)  # latched: it goes nowhere
        assert body.x == 10.0 and body.speed == 0.0


def test_collision_with_an_obstacle_is_reported_once_and_not_entered():
    obstacles = np.zeros((80, 80), bool)
    obstacles[:, 60:] = True  # a wall at x >= 15 m
    body = RoverDynamics(plane(obstacles=obstacles), PARAMS, x=12.0, y=10.0, yaw=0.0)
    steps = run(body, [1.0] * 6, 6.0)
    assert sum(s.collided_obstacle for s in steps) == 1
    assert steps[-1].collided and steps[-1].collision_with == "obstacle"
    # The rectangle's nose stops at the wall (half its length ahead of the centre), not a circle's rim.
    half_length = PARAMS.footprint_length_m / 2.0
    assert 15.0 - half_length - 1e-4 < body.x <= 15.0 - half_length
    # Backing away ends the contact; driving in again is a new one.
    steps = run(body, [-0.5] * 6, 1.0) + run(body, [1.0] * 6, 2.0)
    assert not steps[50].collided
    assert sum(s.collided_obstacle for s in steps) == 1


@pytest.mark.parametrize("dt", [0.005, 0.01, 0.02])
def test_a_head_on_stop_leaves_the_static_wheel_loads(dt):
    """Into a wall at 1.5 m/s on the level: the stop is an impact, not a sustained deceleration, so the
    loads of the steps after it are the static ones (before, the stop's ``v / dt`` loaded the next step's
    front wheels: [221, 0, 0, 221, 0, 0] N at every dt). The step that stopped still records it (the IMU's
    specific force x)."""
    obstacles = np.zeros((80, 80), bool)
    obstacles[:, 60:] = True  # a wall at x >= 15 m
    body = RoverDynamics(plane(obstacles=obstacles), PARAMS, x=10.0, y=10.0, yaw=0.0)
    still = RoverDynamics(plane(), PARAMS, x=10.0, y=10.0, yaw=0.0)
    static = still.step(dt, [0.0] * 6, VOLTS).normal_forces_n
    steps = [body.step(dt, [1.5] * 6, VOLTS) for _ in range(round(4.0 / dt))]
    hit = next(i for i, s in enumerate(steps) if s.collided_obstacle)
    assert steps[hit - 1].speed_mps > 1.4 and steps[hit].speed_mps == 0.0
    assert steps[hit].longitudinal_accel_mps2 < -1.4 / dt  # the impact, in the step that stopped
    after = steps[hit + 1 : hit + 4] + [body.step(dt, [0.0] * 6, VOLTS) for _ in range(3)]
    for step in after:  # still pushing, then parked
        assert step.normal_forces_n == pytest.approx(static, rel=1e-12)
        assert step.collided and step.speed_mps == 0.0


def test_leaving_the_map_is_a_boundary_collision():
    body = RoverDynamics(plane(size=(40, 40)), PARAMS, x=5.0, y=5.0, yaw=math.pi)
    steps = run(body, [1.0] * 6, 8.0)
    assert steps[-1].collision_with == "boundary"
    assert PARAMS.footprint_length_m / 2.0 <= body.x < PARAMS.footprint_length_m / 2.0 + 1e-4


def corridor(y_low_m, y_high_m, size=(80, 80), res=0.25):
    """Obstacles everywhere but a corridor along x between y_low_m and y_high_m (cell edges)."""
    obstacles = np.ones(size, bool)
    obstacles[round(y_low_m / res) : round(y_high_m / res), :] = False
    return obstacles


def test_drives_lengthwise_through_a_corridor_narrower_than_its_diagonal():
    footprint = Footprint.of(PARAMS)
    assert PARAMS.footprint_width_m < 1.0 < 2.0 * footprint.circumscribed_radius_m
    body = RoverDynamics(plane(obstacles=corridor(9.5, 10.5)), PARAMS, x=2.0, y=10.0, yaw=0.0)
    steps = run(body, [1.0] * 6, 5.0)
    assert not any(s.collided for s in steps)
    assert body.x > 6.5 and body.y == pytest.approx(10.0)


def test_turning_on_the_spot_next_to_a_wall_its_corner_hits_it():
    """Side 0.15 m from a wall: the front-left corner (at the circumscribed radius r, angle phi off the
    heading) swings into it once r sin(yaw + phi) reaches the wall, 0.5 m from the centre."""
    obstacles = np.zeros((80, 80), bool)
    obstacles[42:, :] = True  # a wall at y >= 10.5 m, on the rover's left
    body = RoverDynamics(plane(obstacles=obstacles), PARAMS, x=10.0, y=10.0, yaw=0.0)
    footprint = Footprint.of(PARAMS)
    radius = footprint.circumscribed_radius_m
    phi = math.atan2(PARAMS.footprint_width_m, PARAMS.footprint_length_m)
    contact_yaw = math.asin(0.5 / radius) - phi
    steps = run(body, [-0.4] * 3 + [0.4] * 3, 2.0)  # left turn: ~0.8 rad/s, far past contact_yaw
    assert sum(s.collided_obstacle for s in steps) == 1
    assert steps[-1].collided and steps[-1].collision_with == "obstacle"
    assert body.yaw == pytest.approx(contact_yaw, abs=1e-4) and body.yaw <= contact_yaw
    assert body.yaw_rate == 0.0 and (body.x, body.y) == pytest.approx((10.0, 10.0), abs=1e-9)
    assert not footprint_collides(body.terrain, (body.x, body.y, body.yaw), footprint)
    # Turning the other way swings the corner out again: the contact ends.
    steps = run(body, [0.4] * 3 + [-0.4] * 3, 0.5)
    assert not steps[-1].collided and body.yaw < contact_yaw - 0.1


def test_an_obstacle_appearing_on_the_rover_lets_it_back_out_but_not_go_deeper():
    body = RoverDynamics(plane(), PARAMS, x=10.0, y=10.0, yaw=0.0)
    obstacles = np.zeros((80, 80), bool)
    obstacles[:, 41:] = True  # a wall at x >= 10.25 m: the nose (x + 0.45) is 0.2 m into it
    body.set_terrain(plane(obstacles=obstacles))
    steps = run(body, [0.5] * 6, 0.5)
    assert body.x == 10.0 and all(s.collided and s.collision_with == "obstacle" for s in steps)
    steps = run(body, [-0.5] * 6, 1.0)
    assert body.x < 10.25 - PARAMS.footprint_length_m / 2.0 and not steps[-1].collided


def test_deterministic():
    terrain = plane(grade_x=0.1, grade_y=-0.05)
    wheels = [0.8, 0.8, 0.8, 1.0, 1.0, 1.0]
    first = run(RoverDynamics(terrain, PARAMS, x=8.0, y=8.0, yaw=0.3), wheels, 2.0)
    second = run(RoverDynamics(terrain, PARAMS, x=8.0, y=8.0, yaw=0.3), wheels, 2.0)
    assert first == second


def test_bad_input_is_a_typed_error():
    body = RoverDynamics(plane(), PARAMS, x=5.0, y=5.0, yaw=0.0)
    with pytest.raises(DynamicsError, match="time step"):
        body.step(0.0, [0.0] * 6, VOLTS)
    with pytest.raises(DynamicsError, match="6 wheel speeds"):
        body.step(DT, [0.0] * 5, VOLTS)
    with pytest.raises(DynamicsError, match="finite"):
        body.step(DT, [0.0] * 5 + [math.nan], VOLTS)
    with pytest.raises(DynamicsError, match="on the map"):
        RoverDynamics(plane(), PARAMS, x=-1.0, y=5.0, yaw=0.0)


def test_closed_loop_through_the_paper_maze():
    """Planner, follower, mixing and the body together: the rover reaches the goal without touching a wall."""
    terrain = from_maze(MAZE, 3.0, resolution_m=0.25)
    path = Planner(terrain, PARAMS).plan((7.5, 4.5), (4.5, 10.5))
    body = RoverDynamics(terrain, PARAMS, x=7.5, y=4.5, yaw=math.pi)
    follower = PurePursuit(FollowerConfig())
    wheels = [0.0] * 6
    contacts = 0
    arrived = False
    for tick in range(3000):
        if tick % 2 == 0:  # control at 50 Hz, physics at 100 Hz
            cmd = follower.command(body.x, body.y, body.yaw, body.speed, path.points)
            assert abs(cmd.cross_track_error_m) < 1.0
            if cmd.arrived:
                arrived = True
                break
            wheels = mix_skid_steer(cmd.speed_mps, cmd.yaw_rate_rps, PARAMS)
        contacts += body.step(DT, wheels, VOLTS).collided_obstacle
    assert arrived and contacts == 0
    assert math.hypot(body.x - 4.5, body.y - 10.5) <= FollowerConfig().goal_tolerance_m


def test_warm_up_steps_a_copy_and_leaves_the_body_where_it_was() -> None:
    terrain = from_maze(np.full((10, 10), 2), 1.0)
    body = RoverDynamics(terrain, PARAMS, x=5.0, y=5.0, yaw=0.3)
    before = (body.x, body.y, body.yaw, body.speed, body.yaw_rate, body.energy_wh)
    body.warm_up()
    assert (body.x, body.y, body.yaw, body.speed, body.yaw_rate, body.energy_wh) == before
    step = body.step(0.01, [1.0] * 6, 24.0)  # and the real body still steps from its own state
    assert step.energy_wh > 0.0


def test_warm_up_calls_the_kernel_with_the_argument_types_of_the_real_steps(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """numba compiles once per argument types: a warm-up with other types (a read-only map layer copied
    into a writable one) leaves the real first step to compile again, seconds on a cold cache."""
    import numba

    from hil import dynamics_kernel

    terrain = from_maze(np.full((10, 10), 2), 1.0)
    for layer in (terrain.obstacles, terrain.terrain_class, terrain.elevation_m):
        layer.setflags(write=False)  # as the world's map holds them
    body = RoverDynamics(terrain, PARAMS, x=5.0, y=5.0, yaw=0.3)
    seen: list[tuple[object, ...]] = []
    kernel = dynamics_kernel.step_kernel

    def typed(*args: object) -> object:
        seen.append(tuple(numba.typeof(arg) for arg in args))
        return kernel(*args)

    monkeypatch.setattr(dynamics_kernel, "step_kernel", typed)
    body.warm_up()
    body.step(0.01, [1.0] * 6, 24.0)
    assert len(seen) == 2 and seen[0] == seen[1]


@pytest.mark.parametrize(
    "speeds",
    [[0.0] * 5 + [math.inf], [math.inf, -math.inf] + [0.0] * 4, [0.0, math.nan] + [0.0] * 4],
)
def test_wheel_speeds_that_are_not_finite_are_refused(speeds):
    with pytest.raises(DynamicsError, match="finite"):
        check_wheel_speeds(speeds)


def test_finite_wheel_speeds_whose_sum_overflows_are_accepted():
    # The one-sum fast path must not take an overflowing sum of finite numbers for a non-finite speed.
    check_wheel_speeds([1e308] * 6)
    check_wheel_speeds([0.5, -0.5, 1.0, 1.0, 0.0, 2.0])


@pytest.mark.parametrize("stalled", [[0.0] * 5, (0.5,) + (0.0,) * 5, [0.0] * 5 + [math.nan]])
def test_stalled_that_is_not_six_signs_is_refused(stalled):
    body = RoverDynamics(plane(), PARAMS, x=10.0, y=10.0, yaw=0.0)
    with pytest.raises(DynamicsError, match="stalled"):
        body.step(DT, [0.5] * 6, VOLTS, stalled)


def test_six_zeros_stalled_steps_as_no_stall_given():
    # The VESCs' six zeros take the fast path; a list of zeros the full check: both as no stall at all.
    bodies = [RoverDynamics(plane(grade_x=0.1), PARAMS, x=10.0, y=10.0, yaw=0.3) for _ in range(3)]
    for _ in range(50):
        steps = [
            body.step(DT, [0.8, 0.8, 0.8, 1.0, 1.0, 1.0], VOLTS, stalled)
            for body, stalled in zip(bodies, [(), (0.0,) * 6, [0, 0, 0, 0, 0, 0]], strict=True)
        ]
        assert steps[0] == steps[1] == steps[2]
