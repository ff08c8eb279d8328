"""Backing out when dug in (navigator.recovery, ``Guidance.recover``): straight back at the yield speed, no
yaw rate, the set distance or less if the map behind is not clear; then the spot dug in on is an obstacle in
the planner's map and the new path goes round it."""

import math

import numpy as np
import pytest

from navigator.config import PlannerConfig
from navigator.follower import FollowerConfig
from navigator.footprint import Footprint, footprint_collides
from navigator.guidance import DRIVING, RECOVERING, Guidance, GuidanceOutput
from navigator.perception import ObstacleObservation
from navigator.recovery import BACK_OUT_SPARE_S, RECOVERY_BACK_M, dig_in_mark, mark_covers
from navigator.terrain import TerrainMap
from navigator.vehicle import VehicleParams
from navigator.yielding import YIELD_SPEED_MPS

PARAMS = VehicleParams()
TICK_NS = 20_000_000  # 50 Hz
TICK_S = TICK_NS * 1e-9
DUG_IN = (12.0, 10.0, 0.0)  # on the straight path along y = 10, heading east


def _flat(obstacle_xy: tuple[float, float] | None = None) -> TerrainMap:
    rows, cols = 80, 120  # 30 x 20 m at 0.25 m
    obstacles = np.zeros((rows, cols), bool)
    if obstacle_xy is not None:
        col, row = int(obstacle_xy[0] / 0.25), int(obstacle_xy[1] / 0.25)
        obstacles[row - 4 : row + 4, col : col + 2] = True  # a wall 2 m across y, 0.5 m thick
    return TerrainMap(np.zeros((rows, cols)), np.zeros((rows, cols), np.uint8), obstacles, 0.25)


def _dug_in(terrain: TerrainMap) -> tuple[Guidance, ObstacleObservation]:
    guidance = Guidance(terrain, PARAMS, PlannerConfig(), FollowerConfig())
    guidance.set_goal(27.0, 10.0)
    assert guidance.update(0, 2.0, 10.0, 0.0, 0.0).mode == DRIVING  # planned along y = 10
    mark = dig_in_mark(TICK_NS, DUG_IN, PARAMS, 1)
    guidance.recover(TICK_NS, DUG_IN, mark)
    return guidance, mark


def _back_out(guidance: Guidance, ticks: int) -> tuple[list[GuidanceOutput], float]:
    """A rover that moves as commanded, heading east along y = 10 from where it dug in."""
    outputs: list[GuidanceOutput] = []
    x = DUG_IN[0]
    for i in range(2, ticks + 2):
        out = guidance.update(i * TICK_NS, x, 10.0, 0.0, outputs[-1].speed_mps if outputs else 0.0)
        outputs.append(out)
        if out.mode != RECOVERING:
            break
        x += out.speed_mps * TICK_S
    return outputs, x


def test_it_backs_out_straight_the_set_distance_then_drives_a_new_path() -> None:
    guidance, _mark = _dug_in(_flat())
    outputs, x = _back_out(guidance, 500)
    backing = [out for out in outputs if out.mode == RECOVERING]
    assert backing and all(out.speed_mps == -YIELD_SPEED_MPS and out.yaw_rate_rps == 0.0 for out in backing)
    assert outputs[-1].mode == DRIVING and outputs[-1].path_changed
    assert DUG_IN[0] - x == pytest.approx(RECOVERY_BACK_M, abs=YIELD_SPEED_MPS * TICK_S + 1e-9)
    why, mark = guidance.take_recovered() or ("", None)
    assert why == "backed out 1.5 m" and mark is not None and guidance.take_recovered() is None


def test_the_mark_is_in_the_planners_obstacles_and_the_new_path_goes_round_it() -> None:
    guidance, mark = _dug_in(_flat())
    assert not guidance.planner.terrain.obstacles.any()
    # Half the footprint's width, round the front axle: across both front wheels' tracks.
    assert (mark.x, mark.y, mark.radius_m) == (DUG_IN[0] + 0.35, 10.0, 0.35)
    outputs, _x = _back_out(guidance, 500)
    terrain = guidance.planner.terrain
    row, col = int(mark.y / terrain.resolution_m), int(mark.x / terrain.resolution_m)
    assert terrain.obstacles[row, col]
    path = outputs[-1].path
    assert path is not None
    gaps = np.hypot(path.points[:, 0] - mark.x, path.points[:, 1] - mark.y) - mark.radius_m
    assert float(gaps.min()) > PARAMS.footprint_width_m / 2  # round it, not over it
    # It stays for the rest of the run: a new goal plans round it too.
    guidance.set_goal(27.0, 10.0)
    assert guidance.planner.terrain.obstacles[row, col]


def test_it_backs_out_no_further_than_the_map_behind_is_clear() -> None:
    # A wall from x = 10.0 to 10.5: the footprint (rear 0.45 m behind the centre) 0.5 m back reaches it
    # 0.55 m back from where it dug in.
    guidance, _mark = _dug_in(_flat((DUG_IN[0] - 2.0, 10.0)))
    outputs, x = _back_out(guidance, 500)
    moved = DUG_IN[0] - x
    assert moved == pytest.approx(0.55, abs=YIELD_SPEED_MPS * TICK_S + 1e-9) and outputs[-1].mode == DRIVING
    assert not footprint_collides(guidance.planner.terrain, (x, 10.0, 0.0), Footprint.of(PARAMS))
    why, _left = guidance.take_recovered() or ("", None)
    assert why.endswith("an obstacle or the map edge within 0.5 m behind")


def test_a_rover_that_does_not_move_stops_backing_at_the_time_bound_and_leaves_no_mark_under_it() -> None:
    guidance, _mark = _dug_in(_flat())
    outputs = [guidance.update(i * TICK_NS, DUG_IN[0], 10.0, 0.0, 0.0) for i in range(2, 500)]
    modes = [out.mode for out in outputs]
    ended = modes.index(DRIVING)
    assert set(modes[:ended]) == {RECOVERING}
    assert ended * TICK_S == pytest.approx(RECOVERY_BACK_M / YIELD_SPEED_MPS + BACK_OUT_SPARE_S, abs=0.05)
    # A mark under the rover would leave it no path from here, to this goal or any other.
    assert not guidance.planner.terrain.obstacles.any() and outputs[ended].path is not None
    why, mark = guidance.take_recovered() or ("", None)
    assert mark is None and why.endswith("not marked: the spot it dug in on lies under it")


@pytest.mark.parametrize("backed_m", [0.0, 1.0])
def test_a_new_goal_ends_the_back_out_where_the_rover_is_and_says_so(backed_m: float) -> None:
    """The operator chose where to go: no more reversing. What the rover learned of the spot stays (marked
    unless it lies under the rover), and the stack is told, as for any back-out that ends."""
    guidance, mark = _dug_in(_flat())
    x = DUG_IN[0] - backed_m
    assert guidance.update(2 * TICK_NS, x, 10.0, 0.0, 0.0).mode == RECOVERING
    guidance.set_goal(2.0, 2.0)
    assert guidance.update(3 * TICK_NS, x, 10.0, 0.0, 0.0).mode == DRIVING
    why, left = guidance.take_recovered() or ("", None)
    assert why.startswith("a new goal ended the back-out")
    terrain = guidance.planner.terrain
    marked = bool(terrain.obstacles[int(mark.y / terrain.resolution_m), int(mark.x / terrain.resolution_m)])
    assert marked is (left is not None) is (backed_m > 0.0)


def test_the_back_out_ends_at_the_geofence_behind() -> None:
    """Reversed out of the fence, the rover would hold on `geofence` until back inside: stranded."""
    fence = ((11.0, 5.0), (29.0, 5.0), (29.0, 15.0), (11.0, 15.0))  # 1 m behind where it dug in
    guidance = Guidance(_flat(), PARAMS, PlannerConfig(), FollowerConfig(), fence=fence)
    guidance.set_goal(27.0, 10.0)
    guidance.update(0, 2.0, 10.0, 0.0, 0.0)
    guidance.recover(TICK_NS, DUG_IN, dig_in_mark(TICK_NS, DUG_IN, PARAMS, 1))
    _outputs, x = _back_out(guidance, 500)
    assert DUG_IN[0] - x == pytest.approx(0.5, abs=YIELD_SPEED_MPS * TICK_S + 1e-9)
    why, _left = guidance.take_recovered() or ("", None)
    assert why.startswith("backed out 0.5 m: the geofence within 0.5 m behind")


def test_a_mark_covers_a_goal_within_the_planners_clearance() -> None:
    mark = dig_in_mark(0, (5.0, 5.0, math.pi / 2), PARAMS, 3)
    assert mark.obstacle_id == "dug-in-3" and (mark.x, mark.y) == pytest.approx((5.0, 5.35))
    clearance = PARAMS.footprint_radius_m + 0.1
    assert mark_covers(mark, (5.0, 5.35 + 0.35 + clearance - 0.01), clearance)
    assert not mark_covers(mark, (5.0, 5.35 + 0.35 + clearance + 0.01), clearance)


@pytest.mark.parametrize(
    ("start_x", "stops"),
    [(8.0, True), (-20.0, False)],  # 4 m behind, coming on at 1 m/s / 32 m off: out of the 3 s horizon
    ids=["cart-behind", "cart-far-away"],
)
def test_a_cart_predicted_behind_ends_the_back_out(start_x: float, stops: bool) -> None:
    """Reversing blind into a moving obstacle's lane is what the back-off for carts exists to avoid: a
    cart coming up the path behind the rover ends the back-out (the spot is marked, the goal planned
    again, and guidance's usual BLOCKED wait takes the cart from there)."""
    guidance, _mark = _dug_in(_flat())
    cart = ObstacleObservation(TICK_NS, "cart", start_x, 10.0, 0.4, vx=1.0)
    guidance.observe([cart])
    outputs, x = _back_out(guidance, 500)
    why, _left = guidance.take_recovered() or ("", None)
    if stops:
        assert outputs[0].mode != RECOVERING and x == DUG_IN[0]
        assert why.startswith("backed out 0.0 m: moving obstacle cart predicted within 0.5 m behind in 2.8 s")
    else:
        assert why == "backed out 1.5 m"
