"""Guidance stopped for a moving obstacle that is predicted to reach the rover itself: it backs off
(``YIELDING``), bounded, then holds; one that only crosses the path ahead keeps it in plain ``BLOCKED``."""

import numpy as np
import pytest

from navigator.config import PlannerConfig
from navigator.follower import FollowerConfig
from navigator.footprint import Footprint
from navigator.guidance import BLOCKED, DRIVING, YIELDING, Guidance, GuidanceOutput
from navigator.perception import ObstacleObservation
from navigator.terrain import TerrainMap, disc_mask
from navigator.vehicle import VehicleParams
from navigator.yielding import YIELD_MARGIN_M, YIELD_MAX_M, YIELD_MAX_S, YIELD_SPEED_MPS, track_gap

PARAMS = VehicleParams()
TICK_NS = 20_000_000  # 50 Hz
TICK_S = TICK_NS * 1e-9


def _flat() -> TerrainMap:
    rows, cols = 80, 120  # 30 x 20 m at 0.25 m
    return TerrainMap(
        np.zeros((rows, cols)), np.zeros((rows, cols), np.uint8), np.zeros((rows, cols), bool), 0.25
    )


def _guidance(terrain: TerrainMap) -> Guidance:
    guidance = Guidance(terrain, PARAMS, PlannerConfig(), FollowerConfig())
    guidance.set_goal(27.0, 10.0)
    assert guidance.update(0, 2.0, 10.0, 0.0, 0.0).mode == DRIVING  # planned along y = 10
    return guidance


def _cart(t_ns: int, x: float, y: float, vx: float = 0.0, vy: float = -0.8) -> ObstacleObservation:
    return ObstacleObservation(t_ns, "cart", x, y, 0.5, vx=vx, vy=vy)


def _run(
    guidance: Guidance,
    ticks: int,
    rover_x: float,
    cart_x: float,
    cart_y: float,
    vx: float = 0.0,
    vy: float = -0.8,
) -> tuple[list[GuidanceOutput], float]:
    """``ticks`` ticks of a rover that moves as commanded (straight along y = 10, heading east) and a cart
    seen every tick at constant velocity; returns the outputs and the rover's final x."""
    outputs: list[GuidanceOutput] = []
    for i in range(1, ticks + 1):
        t_ns = i * TICK_NS
        t_s = i * TICK_S
        guidance.observe([_cart(t_ns, cart_x + vx * t_s, cart_y + vy * t_s, vx, vy)])
        out = guidance.update(t_ns, rover_x, 10.0, 0.0, outputs[-1].speed_mps if outputs else 0.0)
        outputs.append(out)
        rover_x += out.speed_mps * TICK_S
    return outputs, rover_x


def test_cart_predicted_to_reach_the_rover_makes_it_back_off_then_hold_clear_of_the_track() -> None:
    guidance = _guidance(_flat())
    # The rover stands at x = 10 (footprint x 9.55-10.45); a cart 2.5 m to its left, 0.3 m ahead of its
    # centre, comes down at 0.8 m/s: within 3 s its track crosses the rover's nose.
    outputs, rover_x = _run(guidance, 400, 10.0, 10.3, 12.5)
    modes = [out.mode for out in outputs]
    assert modes[0] == YIELDING
    assert outputs[0].speed_mps == pytest.approx(-YIELD_SPEED_MPS) and outputs[0].yaw_rate_rps == 0.0
    assert outputs[0].speed_limit_reason == "moving_obstacle"
    assert "moving obstacle cart predicted to reach the rover: backing off" in outputs[0].detail
    # It backs off, then holds (BLOCKED) until the cart has passed and the way has been clear, then drives.
    first_hold = modes.index(BLOCKED)
    assert set(modes[:first_hold]) == {YIELDING}
    assert outputs[first_hold].detail.startswith("out of the way")
    assert DRIVING in modes[first_hold:]
    assert [out.detail for out in outputs if "backing off" in out.detail] == [outputs[0].detail]
    # Where it stopped backing, the cart's track (as seen then) cleared its footprint by the margin.
    stop_x = 10.0 - YIELD_SPEED_MPS * TICK_S * first_hold
    t_ns = (first_hold + 1) * TICK_NS
    seen = {"cart": _cart(t_ns, 10.3, 12.5 - 0.8 * t_ns * 1e-9)}
    limit = PlannerConfig().inflation_m + YIELD_MARGIN_M
    assert track_gap(seen, t_ns, (stop_x, 10.0, 0.0), Footprint.of(PARAMS), 3.0).gap_m >= limit
    # The cart's lane is x 9.8-10.8: the nose (centre + 0.45 m) ended more than inflation + margin short.
    assert stop_x + 0.45 < 9.8 - limit
    assert rover_x > 11.0  # and once the way was clear it drove on


def test_cart_that_only_crosses_the_path_ahead_keeps_plain_blocked() -> None:
    guidance = _guidance(_flat())
    # The same cart crossing 4 m ahead of the rover: on the path ahead, nowhere near the rover itself.
    outputs, rover_x = _run(guidance, 100, 10.0, 14.0, 12.5)
    assert [out.mode for out in outputs] == [BLOCKED] * 100
    assert all(out.speed_mps == 0.0 for out in outputs)
    assert [out.detail for out in outputs if out.detail] == ["moving obstacle cart predicted on the path"]
    assert rover_x == 10.0 and guidance.blocker == "cart"


def test_back_off_that_reaches_its_distance_bound_holds_for_the_rest_of_the_wait() -> None:
    guidance = _guidance(_flat())
    # A cart following the rover back at its own reverse speed, 1 m ahead of its centre: always predicted
    # to reach it. After YIELD_MAX_M the rover holds and backs no further, though the threat remains.
    outputs, rover_x = _run(guidance, 500, 14.0, 15.0, 10.0, vx=-YIELD_SPEED_MPS, vy=0.0)
    modes = [out.mode for out in outputs]
    first_hold = modes.index(BLOCKED)
    assert set(modes[:first_hold]) == {YIELDING} and set(modes[first_hold:]) == {BLOCKED}
    assert f"the limit is {YIELD_MAX_M:g} m; holding" in outputs[first_hold].detail
    assert 14.0 - rover_x == pytest.approx(YIELD_MAX_M, abs=YIELD_SPEED_MPS * TICK_S + 1e-9)


def test_back_off_that_reaches_its_time_bound_holds() -> None:
    guidance = _guidance(_flat())
    # The rover does not move although commanded (wheels slipping): after YIELD_MAX_S it holds.
    t_ns, outputs = 0, list[GuidanceOutput]()
    while t_ns <= (YIELD_MAX_S + 1.0) * 1e9:
        t_ns += TICK_NS
        guidance.observe([_cart(t_ns, 10.8, 10.0, vx=-0.01, vy=0.0)])
        outputs.append(guidance.update(t_ns, 10.0, 10.0, 0.0, 0.0))
    modes = [out.mode for out in outputs]
    first_hold = modes.index(BLOCKED)
    assert set(modes[:first_hold]) == {YIELDING} and set(modes[first_hold:]) == {BLOCKED}
    assert first_hold * TICK_S == pytest.approx(YIELD_MAX_S, abs=TICK_S)
    assert f"the limit is {YIELD_MAX_S:g} s; holding" in outputs[first_hold].detail


def test_rover_whose_rear_is_in_the_lane_creeps_forward_out_of_it() -> None:
    guidance = _guidance(_flat())
    # Nearly across: the rover's rear (x 9.55) is in the lane of a cart at x = 9.4 coming down fast;
    # backing would take it further in, so it creeps on until clear, then holds.
    outputs, _rover_x = _run(guidance, 150, 10.0, 9.4, 12.5, vy=-1.0)
    assert outputs[0].mode == YIELDING and outputs[0].speed_mps == pytest.approx(YIELD_SPEED_MPS)
    assert (
        "moving obstacle cart predicted to reach the rover: creeping forward out of its way"
        in outputs[0].detail
    )
    modes = [out.mode for out in outputs]
    out_of_it = next(k for k, mode in enumerate(modes) if mode != YIELDING)
    assert outputs[out_of_it].detail.startswith("out of the way") and YIELDING not in modes[out_of_it:]
    # Held where the rear had cleared the lane (x 8.9-9.9) by the margin (the cart went on down).
    held_x = 10.0 + YIELD_SPEED_MPS * TICK_S * out_of_it
    assert held_x - 0.45 > 9.9 + PlannerConfig().inflation_m + YIELD_MARGIN_M - YIELD_SPEED_MPS * TICK_S


def test_back_off_with_an_obstacle_behind_and_no_way_forward_holds_at_once() -> None:
    terrain = _flat()
    guidance = _guidance(terrain)
    guidance.observe([ObstacleObservation(0, "rock", 8.8, 10.0, 0.5)])  # just behind the rover at x = 10
    assert guidance.update(0, 10.0, 10.0, 0.0, 0.0).mode == DRIVING  # static: into the map
    assert guidance.planner.terrain.obstacles[disc_mask(terrain, 8.8, 10.0, 0.5)].all()
    # The cart comes down across the rover's nose: forward would take it into the lane, back is the rock.
    outputs, rover_x = _run(guidance, 50, 10.0, 10.3, 12.5)
    assert [out.mode for out in outputs] == [BLOCKED] * 50
    assert outputs[0].detail.endswith(
        "no back-off from moving obstacle cart: neither backing nor creeping forward 0.5 m is clear of the "
        "map and further from the track; holding"
    )
    assert rover_x == 10.0


def test_rover_straddling_the_lane_backs_out_of_it_rather_than_hold_in_its_middle() -> None:
    # The cart's lane (x 9.5-10.5) crosses the rover's centre. Backing a little leaves the track across the
    # footprint (gap -radius either way) and reached as soon: by gap and time alone that was "no further",
    # the rover held in the middle of the lane and was hit (scenarios/carts.toml, seed 2, cart-c).
    footprint = Footprint.of(PARAMS)
    seen = {"cart": _cart(0, 10.0, 12.5, vy=-1.0)}
    here = track_gap(seen, 0, (10.0, 10.0, 0.0), footprint, 3.0)
    back = track_gap(seen, 0, (9.75, 10.0, 0.0), footprint, 3.0)  # the track still within the length
    assert here.gap_m == back.gap_m == -0.5 and here.reach_s == back.reach_s
    assert back.further_than(here) and not here.further_than(back)
    guidance = _guidance(_flat())
    outputs, _ = _run(guidance, 300, 10.0, 10.0, 13.6, vy=-0.8)
    modes = [out.mode for out in outputs]
    assert YIELDING in modes and not any("no back-off" in out.detail for out in outputs)
    first_hold = modes.index(BLOCKED, modes.index(YIELDING))
    assert outputs[first_hold].detail.startswith("out of the way")
    # It left the lane by the margin: its nose (centre + 0.45 m) short of x 9.5 - inflation - margin.
    held_x = 10.0 - YIELD_SPEED_MPS * TICK_S * sum(1 for m in modes[:first_hold] if m == YIELDING)
    assert held_x + 0.45 < 9.5 - (PlannerConfig().inflation_m + YIELD_MARGIN_M) + 1e-9


def _guidance_with(planner: PlannerConfig) -> Guidance:
    guidance = Guidance(_flat(), PARAMS, planner, FollowerConfig())
    guidance.set_goal(27.0, 10.0)
    assert guidance.update(0, 2.0, 10.0, 0.0, 0.0).mode == DRIVING
    return guidance


def test_the_back_off_speed_and_distance_bound_are_the_configs() -> None:
    # The distance-bound case above with [planner] yield_speed_mps = 0.3, yield_max_m = 1.2.
    guidance = _guidance_with(PlannerConfig(yield_speed_mps=0.3, yield_max_m=1.2))
    outputs, rover_x = _run(guidance, 500, 14.0, 15.0, 10.0, vx=-0.3, vy=0.0)
    modes = [out.mode for out in outputs]
    assert outputs[0].mode == YIELDING and outputs[0].speed_mps == pytest.approx(-0.3)
    assert outputs[0].speed_limit_mps == pytest.approx(0.3)
    first_hold = modes.index(BLOCKED)
    assert "the limit is 1.2 m; holding" in outputs[first_hold].detail
    assert 14.0 - rover_x == pytest.approx(1.2, abs=0.3 * TICK_S + 1e-9)


def test_a_back_off_speed_of_zero_holds_in_the_carts_way() -> None:
    guidance = _guidance_with(PlannerConfig(yield_speed_mps=0.0))
    outputs, rover_x = _run(guidance, 100, 10.0, 10.3, 12.5)
    assert {out.mode for out in outputs} == {BLOCKED} and rover_x == 10.0


def test_a_mission_speed_limit_does_not_slow_a_back_off() -> None:
    # The back-off is a safety manoeuvre with its own speed (yield_speed_mps); a mission's DO_CHANGE_SPEED
    # below it limits the driving, not the getting out of a cart's way.
    guidance = _guidance(_flat())
    guidance.limit_speed(0.2)
    outputs, _ = _run(guidance, 5, 10.0, 10.3, 12.5)
    assert outputs[0].mode == YIELDING and outputs[0].speed_mps == pytest.approx(-YIELD_SPEED_MPS)
    assert YIELD_SPEED_MPS > 0.2 and outputs[0].speed_limit_reason == "moving_obstacle"


def test_the_back_off_does_not_leave_the_geofence() -> None:
    """The supervisor holds a rover outside `[safety] fence` until it is back inside: a back-off out of it
    would strand the rover by its own move. The same cart as above, the fence's west edge 0.3 m behind."""
    fence = ((9.7, 0.0), (30.0, 0.0), (30.0, 20.0), (9.7, 20.0))
    guidance = Guidance(_flat(), PARAMS, PlannerConfig(), FollowerConfig(), fence=fence)
    guidance.set_goal(27.0, 10.0)
    assert guidance.update(0, 10.0, 10.0, 0.0, 0.0).mode == DRIVING
    outputs, _rover_x = _run(guidance, 100, 10.0, 10.3, 12.5)
    assert all(out.speed_mps >= 0.0 for out in outputs)  # never backing
    assert "no back-off from moving obstacle cart" in outputs[0].detail
