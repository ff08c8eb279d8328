"""Obstacle-avoidance success with moving obstacles (judged where they were at each time) and collisions
(a collision always means "encountered, not avoided")."""

from __future__ import annotations

import io
import json
import math

import pytest

from logs.clock import to_ns
from logs.metrics import compute_metrics
from logs.recorder import McapRecorder
from logs.topics import TRUTH_CONTACTS, TRUTH_POSE, planar_pose, stamp

# The rover drives y = 0 from x = 0 to x = 20 at 1 m/s (t = x seconds).
TRACK = [(float(x), 0.0) for x in range(21)]
# A cart walking x = 10 from y = 12 down to y = -12 at 2 m/s: at y = 0 at t = 6 s (rover at x = 6, 4 m
# away: beyond radius 0.5 + margin 1.5) and never near the rover at any time; its track crosses the
# rover's path, so judging its waypoints or its start as if it stood still would get it wrong.
PASSED_BEHIND = {
    "id": "early-cart",
    "radius": 0.5,
    "waypoints": [[10.0, 12.0], [10.0, -12.0]],
    "speed_mps": 2.0,
}
# A cart that waits 7 s at its first waypoint, 8 m off the path, then drives down x = 15 at 1 m/s: at
# y = 0 at t = 15 s, exactly where the rover is.
RAMMER = {
    "id": "rammer",
    "radius": 0.5,
    "waypoints": [[15.0, 8.0], [15.0, -8.0]],
    "speed_mps": 1.0,
    "start_s": 7.0,
}
STATIC = [{"id": "far-rock", "x": 5.0, "y": 9.0, "radius": 1.0}]  # 8 m off the track: never in the way


def _run(
    contacts: list[tuple[float, str]],
    moving: list[dict] | None,
    *,
    shift_ns: int = 0,
    world: dict[str, str] | None = None,
    static: list[dict] | None = None,
) -> bytes:
    """The recording; every time later by ``shift_ns`` (a world started then on the clock that stamps the
    log, as the real-time peer's monotonic clock), ``world`` its ``world`` metadata record if any."""
    buffer = io.BytesIO()
    obstacles = json.dumps(STATIC if static is None else static)
    scenario = {"path_tolerance_m": "0.5", "encounter_margin_m": "1.5", "obstacles_json": obstacles}
    if moving is not None:
        scenario["moving_obstacles_json"] = json.dumps(moving)
    with McapRecorder(buffer) as recorder:
        recorder.add_metadata("scenario", scenario)
        if world is not None:
            recorder.add_metadata("world", world)
        for index, (x, y) in enumerate(TRACK):
            t = shift_ns + to_ns(float(index))
            recorder.publish(
                TRUTH_POSE, t, {"timestamp": stamp(t), "frame_id": "enu", "pose": planar_pose(x, y, 0.0)}
            )
        for t_s, obstacle_id in contacts:
            t = shift_ns + to_ns(t_s)
            contact = {
                "timestamp": stamp(t),
                "kind": "collision",
                "obstacle_id": obstacle_id,
                "x": 0.0,
                "y": 0.0,
            }
            recorder.publish(TRUTH_CONTACTS, t, contact)
    return buffer.getvalue()


def test_moving_obstacles_are_judged_where_they_were_at_each_time() -> None:
    metrics = compute_metrics(io.BytesIO(_run([], [PASSED_BEHIND, RAMMER])))
    # the rammer met the rover (and was avoided: no collision); the early cart and the far rock did not
    assert (metrics.obstacles_encountered, metrics.obstacles_avoided) == (1, 1)
    assert metrics.obstacle_avoidance_success_pct == pytest.approx(100.0)


def test_a_collision_with_a_moving_obstacle_is_not_an_avoidance() -> None:
    metrics = compute_metrics(io.BytesIO(_run([(15.0, "rammer")], [PASSED_BEHIND, RAMMER])))
    assert metrics.collisions == 1
    assert (metrics.obstacles_encountered, metrics.obstacles_avoided) == (1, 0)
    assert metrics.obstacle_avoidance_success_pct == pytest.approx(0.0)


def test_a_collision_counts_whatever_the_geometry_says() -> None:
    # a contact naming an obstacle the sampled track never came near (moving obstacles unknown here)
    metrics = compute_metrics(io.BytesIO(_run([(5.0, "far-rock")], None)))
    assert (metrics.obstacles_encountered, metrics.obstacles_avoided) == (1, 0)
    assert metrics.obstacle_avoidance_success_pct == pytest.approx(0.0)


def test_a_bad_moving_obstacle_entry_is_skipped_and_described() -> None:
    broken = [{"id": "one-point", "radius": 0.5, "waypoints": [[1.0, 1.0]], "speed_mps": 1.0}, RAMMER]
    metrics = compute_metrics(io.BytesIO(_run([], broken)))
    assert metrics.obstacles_encountered == 1
    assert any("moving_obstacles_json[0]" in problem for problem in metrics.problems)


@pytest.mark.parametrize(("cart", "encountered"), [(PASSED_BEHIND, 0), (RAMMER, 1)])
def test_moving_obstacles_move_from_the_recorded_start_of_the_world(cart: dict, encountered: int) -> None:
    # A real-time peer's world started 10^6 s (and a bit) after the machine booted: each cart is where it
    # was in the recording that starts at 0. (Timed from the boot instead, the early cart would meet the
    # rover and the rammer would miss it.)
    epoch_ns = to_ns(1_000_005.0)
    recording = _run([], [cart], shift_ns=epoch_ns, world={"epoch_ns": str(epoch_ns)})
    metrics = compute_metrics(io.BytesIO(recording))
    assert metrics.obstacles_encountered == encountered
    assert not metrics.problems


def test_an_unusable_world_start_is_described_and_taken_as_zero() -> None:
    metrics = compute_metrics(io.BytesIO(_run([], [PASSED_BEHIND, RAMMER], world={"epoch_ns": "soon"})))
    assert (metrics.obstacles_encountered, metrics.obstacles_avoided) == (1, 1)  # timed from 0
    assert [p for p in metrics.problems if "world.epoch_ns" in p] == [
        "metadata world.epoch_ns='soon' is not an int64 >= 0; used 0"
    ]


def test_the_closest_approach_is_the_least_centre_to_edge_distance_and_names_the_obstacle() -> None:
    # Static only: the far rock at (5, 9), radius 1, from the track y = 0: 9 - 1 = 8 m.
    alone = compute_metrics(io.BytesIO(_run([], None)))
    assert alone.closest_obstacle_m == pytest.approx(8.0)
    assert alone.closest_obstacle_id == "far-rock"
    # With the carts, judged where each was at each sample: the early cart is nearest at t = 7 s, at
    # (10, -2) with the rover at (7, 0) (hypot(3, 2) less its 0.5 m radius); the rammer stands where the
    # rover is at t = 15 s: -0.5 m, inside its radius.
    both = compute_metrics(io.BytesIO(_run([], [PASSED_BEHIND])))
    assert both.closest_obstacle_m == pytest.approx(math.hypot(3.0, 2.0) - 0.5)
    assert both.closest_obstacle_id == "early-cart"
    rammed = compute_metrics(io.BytesIO(_run([], [PASSED_BEHIND, RAMMER])))
    assert rammed.closest_obstacle_m == pytest.approx(-0.5)
    assert rammed.closest_obstacle_id == "rammer"
    assert rammed.to_dict()["closest_obstacle_m"] == -0.5


def test_an_obstacle_whose_distance_is_not_a_number_does_not_hide_the_nearest() -> None:
    # Waypoints at +-1e308 overflow the cart's walk to NaN: whatever its place in the list (first of all
    # here: no static obstacle), the rammer at -0.5 m stays the closest approach (min() with a NaN key
    # answers by the order).
    broken = {
        "id": "overflow",
        "radius": 0.5,
        "waypoints": [[1e308, 1e308], [-1e308, -1e308]],
        "speed_mps": 1.0,
    }
    for moving in ([broken, RAMMER], [RAMMER, broken]):
        metrics = compute_metrics(io.BytesIO(_run([], moving, static=[])))
        assert metrics.closest_obstacle_id == "rammer"
        assert metrics.closest_obstacle_m == pytest.approx(-0.5)
