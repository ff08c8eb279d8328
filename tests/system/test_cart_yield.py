"""A rover stopped for a crossing cart with its nose in the cart's lane backs out of the way.

``tests/data/cart_in_lane.toml``: the cart comes into view as the rover is over its lane. Before the
back-off (``navigator.yielding``) the rover stopped BLOCKED there and the cart ran into it (collisions 1,
obstacle-avoidance 0 %); now it backs off, holds, lets the cart pass and reaches the goal.
"""

from __future__ import annotations

from hil.trial import TrialResult
from logs import topics
from logs.reader import read_messages


def test_rover_in_the_carts_lane_backs_off_and_is_not_hit(cart_lane_trial: TrialResult) -> None:
    metrics = cart_lane_trial.metrics
    assert metrics.obstacles_encountered == 1, "the cart never came near: the scenario no longer tests this"
    assert metrics.collisions == 0 and metrics.obstacle_avoidance_success_pct == 100.0
    assert metrics.goal_reached and cart_lane_trial.success, cart_lane_trial.failures
    contacts = list(read_messages(cart_lane_trial.mcap_path, topics=[topics.TRUTH_CONTACTS]))
    assert not [c for c in contacts if c.message.get("obstacle_id") == "cart-a"]


def test_back_off_is_one_event_with_its_cause_and_shows_on_the_state(cart_lane_trial: TrialResult) -> None:
    events = [r.message for r in read_messages(cart_lane_trial.mcap_path, topics=[topics.SAFETY_EVENTS])]
    yielding = [e for e in events if e["kind"] == "guidance.yielding"]
    assert [e["detail"] for e in yielding] == [
        "moving obstacle cart-a predicted to reach the rover: backing off"
    ]
    assert any(e["kind"] == "guidance.blocked" and e["detail"].startswith("out of the way") for e in events)
    # Reversing against the wheels' commands is motion, not a stuck rover or a stalled wheel.
    assert not [e for e in events if e["kind"].startswith("failsafe.")]
    states = [r.message for r in read_messages(cart_lane_trial.mcap_path, topics=[topics.NAVIGATOR_STATE])]
    backing = [s for s in states if s["mode"] == "YIELDING"]
    assert len(backing) > 50  # seconds of backing at 50 Hz
    assert all(s["target_speed_mps"] < 0.0 and s["safety_mode"] == "DRIVING" for s in backing)


def test_the_rover_really_went_backwards_out_of_the_lane(cart_lane_trial: TrialResult) -> None:
    states = [
        (r.log_time_ns, r.message["mode"])
        for r in read_messages(cart_lane_trial.mcap_path, topics=[topics.NAVIGATOR_STATE])
    ]
    began = next(t for t, mode in states if mode == "YIELDING")
    resumed = next(t for t, mode in states if t > began and mode == "DRIVING")
    truth = [
        (r.log_time_ns, r.message["pose"]["position"]["x"])
        for r in read_messages(cart_lane_trial.mcap_path, topics=[topics.TRUTH_POSE])
    ]
    stood_at = max(x for t, x in truth if t <= began)
    backed_to = min(x for t, x in truth if began <= t <= resumed)
    # The lane is x 11.5-12.5; the rover's nose (0.45 m ahead of its centre) stood in it, and left it.
    assert stood_at + 0.45 > 11.5
    assert backed_to + 0.45 < 11.5
