"""``CommandWatch`` on hand-made samples: what confirms, refuses or leaves a command unconfirmed."""

from __future__ import annotations

import math
from typing import Any

import pytest

from logs.command_watch import CommandWatch, Verdict, expected_effect
from logs.telemetry import TelemetrySample


def state(
    reason: str = "cruise", goal: tuple[float, float] | None = None, mode: str = "DRIVING"
) -> TelemetrySample:
    where: dict[str, Any] = {"x": None, "y": None} if goal is None else {"x": goal[0], "y": goal[1]}
    return TelemetrySample(
        "navigator/state",
        1,
        {"mode": mode, "goal": where, "speed_limit_reason": reason, "speed_limit_mps": 1.0},
    )


def event(kind: str, detail: str) -> TelemetrySample:
    return TelemetrySample("safety/events", 1, {"kind": kind, "severity": "info", "detail": detail})


def test_estop_is_not_confirmed_by_a_driving_state_but_by_the_latch_or_the_estop_state() -> None:
    watch = CommandWatch("estop")
    watch.observe(state("cruise"))
    watch.observe(event("mode", "ESTOP -> IDLE: nothing to drive to"))  # leaving ESTOP is the opposite
    watch.observe(TelemetrySample("estimator/pose", 1, {"kind": "failsafe.estop"}))  # not a watched topic
    assert watch.outcome is None and not watch.decided.is_set()
    watch.observe(event("failsafe.estop", "emergency stop from ground station"))
    assert watch.decided.is_set() and watch.outcome is not None
    assert watch.outcome.verdict is Verdict.CONFIRMED and "failsafe.estop" in watch.outcome.detail

    by_state = CommandWatch("estop")
    by_state.observe(state("safety estop", mode="IDLE"))
    assert by_state.outcome is not None and by_state.outcome.confirmed

    by_mode = CommandWatch("estop")
    by_mode.observe(event("mode", "DRIVING -> ESTOP: emergency stop from ground station"))
    assert by_mode.outcome is not None and by_mode.outcome.confirmed


def test_resume_waits_for_the_state_to_leave_estop_and_says_what_holds_instead() -> None:
    watch = CommandWatch("resume")
    watch.observe(state("safety estop"))
    watch.observe(event("failsafe.estop", "emergency stop from ground station"))
    assert watch.outcome is None
    watch.observe(state("safety hold"))
    assert watch.outcome is not None and watch.outcome.confirmed
    assert "'safety hold'" in watch.outcome.detail  # out of ESTOP, but the operator learns it still holds

    cleared = CommandWatch("resume")
    cleared.observe(event("cleared.estop", "resume from ground station"))
    assert cleared.outcome is not None and cleared.outcome.confirmed


def test_goal_is_confirmed_only_by_its_own_coordinates_and_refused_by_its_own_rejection() -> None:
    watch = CommandWatch("goal", 3.5, -2.0)
    watch.observe(state(goal=None, mode="IDLE"))
    watch.observe(state(goal=(3.5, 2.0)))
    watch.observe(TelemetrySample("navigator/state", 1, {"goal": "3.5,-2", "speed_limit_reason": "x"}))
    watch.observe(event("goal_rejected", "goal (9.00, 9.00) is outside the geofence"))
    assert watch.outcome is None
    watch.observe(state(goal=(3.5, -2.0), mode="PLANNING"))
    assert watch.outcome is None and watch.accepted  # taken, but the plan's outcome is not known yet
    watch.observe(state(goal=(3.5, -2.0), mode="DRIVING"))
    assert watch.outcome is not None and watch.outcome.confirmed
    assert "mode DRIVING, goal (3.50, -2.00)" in watch.outcome.detail

    refused = CommandWatch("goal", 30.0, 3.0)
    refused.observe(event("goal_rejected", "goal (30.00, 3.00) is outside the geofence"))
    assert refused.outcome is not None and refused.outcome.verdict is Verdict.REJECTED
    assert "refused" in refused.outcome.detail and "geofence" in refused.outcome.detail


def test_a_goal_taken_then_found_unreachable_is_refused_with_the_planners_reason() -> None:
    watch = CommandWatch("goal", 30.0, 3.0)
    watch.observe(event("guidance.no_path", "cannot plan: an earlier goal"))  # before ours: not about it
    watch.observe(event("goal", "new goal (30.00, 3.00)"))
    assert watch.outcome is None and watch.accepted
    watch.observe(event("guidance.no_path", "cannot plan: goal position is not on the map"))
    assert watch.outcome is not None and watch.outcome.verdict is Verdict.REJECTED
    assert "cannot reach it" in watch.outcome.detail and "not on the map" in watch.outcome.detail

    # The reason's event lost (best-effort stream): the NO_PATH state alone still refuses.
    by_state = CommandWatch("goal", 6.5, 4.5)
    by_state.observe(state(goal=(6.5, 4.5), mode="WAITING_ESTIMATE"))
    by_state.observe(state(goal=(6.5, 4.5), mode="NO_PATH"))
    assert by_state.outcome is not None and by_state.outcome.verdict is Verdict.REJECTED
    assert "found no path" in by_state.outcome.detail and "mode NO_PATH" in by_state.outcome.detail
    # The reason travels on safety/events and may come after the state: it is added, and the verdict stands.
    assert by_state.decided.is_set() and not by_state.complete.is_set()
    by_state.observe(event("guidance.no_path", "cannot plan: goal cell (18, 26) is lethal"))
    assert by_state.complete.is_set() and by_state.outcome.verdict is Verdict.REJECTED
    assert "cannot reach it" in by_state.outcome.detail and "is lethal" in by_state.outcome.detail


def test_a_state_from_before_the_goal_was_taken_decides_nothing() -> None:
    # The same goal sent again: the rover's old state already shows it DRIVING (or NO_PATH). Only what
    # follows the acceptance (its event, or a state after another goal) is the answer to this send.
    watch = CommandWatch("goal", 1.0, 2.0)
    watch.observe(state(goal=(1.0, 2.0), mode="DRIVING"))
    watch.observe(state(goal=(1.0, 2.0), mode="NO_PATH"))
    assert watch.outcome is None and not watch.accepted
    watch.observe(event("goal", "new goal (1.00, 2.00)"))
    watch.observe(state(goal=(1.0, 2.0), mode="DRIVING"))
    assert watch.outcome is not None and watch.outcome.confirmed

    after_another = CommandWatch("goal", 1.0, 2.0)
    after_another.observe(state(goal=(5.0, 5.0), mode="DRIVING"))
    after_another.observe(state(goal=(1.0, 2.0), mode="DRIVING"))
    assert after_another.outcome is not None and after_another.outcome.confirmed


def test_the_first_verdict_stands() -> None:
    watch = CommandWatch("goal", 30.0, 3.0)
    watch.observe(event("goal_rejected", "goal (30.00, 3.00) is outside the geofence"))
    watch.observe(state(goal=(30.0, 3.0)))
    assert watch.outcome is not None and watch.outcome.verdict is Verdict.REJECTED
    assert watch.seen == {"safety/events": 1, "navigator/state": 1}


def test_what_was_seen_says_whether_the_rover_published_anything() -> None:
    watch = CommandWatch("estop")
    assert "heard nothing" in watch.what_was_seen()
    watch.observe(event("failsafe.gps", "no GPS for 2 s"))
    assert "1 on safety/events" in watch.what_was_seen()
    watch.observe(state("cruise", goal=(1.0, math.inf)))
    assert "the last navigator/state: mode DRIVING, goal none" in watch.what_was_seen()


def test_expected_effect_names_the_stream_and_a_goal_needs_coordinates() -> None:
    assert "ESTOP transition" in expected_effect("estop") and "safety/events" in expected_effect("estop")
    assert "leaving ESTOP" in expected_effect("resume")
    assert "goal becoming (1.00, 2.00)" in expected_effect("goal", 1.0, 2.0)
    assert "DRIVING" in expected_effect("goal", 1.0, 2.0)
    with pytest.raises(ValueError, match="x and y"):
        CommandWatch("goal", 1.0, None)
