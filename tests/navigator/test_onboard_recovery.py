"""The onboard stack held for no progress recovers (navigator.onboard_recovery): it backs out, marks the spot
and plans round it, at most ``recovery_attempts`` times a goal or resume, then holds with
``recovery.gave_up``; learning goes first; off, it holds as before. On the lockstep rig (real stack,
simulated rover, fake clock and links), with the supervisor shown a position that goes nowhere while
guidance drives: the rover dug in, as the supervisor sees it."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from navigator.route_guidance import Goal, Mode
from navigator.safety import NO_PROGRESS, TIP_OVER, SafetyDecision, SafetyInputs
from navigator.terrain import disc_mask
from tests.runtime.rig import Rig, rig_config

WINDOW_S = 4.0  # [safety] progress_time_s: the shortest it takes


class DugIn:
    """The supervisor's view of a rover that goes nowhere while guidance drives: the estimated position it
    judges progress on stays where guidance's ``DRIVING`` began (backing out, it sees the real one)."""

    def __init__(self, rig: Rig, monkeypatch: pytest.MonkeyPatch) -> None:
        self.on = True
        self._at: tuple[float, float] | None = None
        stack = rig.stack
        update = stack.safety.update

        def frozen(inputs: SafetyInputs, *args: Any) -> SafetyDecision:
            if not self.on or stack.mode is not Mode.DRIVING or inputs.position_xy is None:
                self._at = None
                return update(inputs, *args)
            if self._at is None:
                self._at = inputs.position_xy
            return update(inputs._replace(position_xy=self._at), *args)

        monkeypatch.setattr(stack.safety, "update", frozen)


def _rig(**planner: Any) -> Rig:
    config = rig_config(progress_time_s=WINDOW_S)
    planner_config = dataclasses.replace(config.planner, **planner)
    # A 0.25 m grid, as the shipped maps: on the rig's default 2 m cells a mark fills the cell it backed into.
    return Rig(dataclasses.replace(config, planner=planner_config), resolution_m=0.25)


@pytest.fixture
def rig() -> Iterator[Rig]:
    made = _rig()
    yield made
    made.close()


@pytest.fixture
def make_rig() -> Iterator[Callable[..., Rig]]:
    """``_rig`` with planner settings of the test's own, each closed after the test."""
    made: list[Rig] = []

    def make(**planner: Any) -> Rig:
        made.append(_rig(**planner))
        return made[-1]

    yield make
    for each in made:
        each.close()


def _kinds(rig: Rig) -> list[str]:
    return [m["kind"] for topic, _t, m in rig.sink.records if topic == "safety/events"]


def _recovery_kinds(rig: Rig) -> list[str]:
    return [k for k in _kinds(rig) if k.startswith("recovery.") or k.endswith(NO_PROGRESS)]


def test_dug_in_it_backs_out_marks_and_plans_round_twice_then_holds(
    rig: Rig, monkeypatch: pytest.MonkeyPatch
) -> None:
    DugIn(rig, monkeypatch)
    rig.run_until(lambda: bool(rig.events("recovery.gave_up")), 40.0, "the recoveries given up")
    round_trip = ["failsafe.no_progress", "recovery.backing_out", "cleared.no_progress", "recovery.replanned"]
    assert _recovery_kinds(rig) == [*round_trip, *round_trip, "failsafe.no_progress", "recovery.gave_up"]
    states = [m for topic, _t, m in rig.sink.records if topic == "navigator/state"]
    backing = [s for s in states if s["mode"] == "RECOVERING"]
    # Each back-out's first tick is the hold's (the wheels still held); from the next the supervisor lets
    # it move, straight back.
    moving = [s for s in backing if s["safety_mode"] == "DRIVING"]
    assert [s["safety_mode"] for s in backing if s not in moving] == ["HOLD", "HOLD"] and len(moving) > 100
    assert all(s["target_speed_mps"] < 0.0 and s["target_yaw_rate_rps"] == 0.0 for s in moving)
    # Each mark went into the recording and the planner's map, and each new path goes round it.
    marks = [
        o for topic, _t, m in rig.sink.records if topic == "perception/obstacles" for o in m["obstacles"]
    ]
    assert [o["id"] for o in marks] == ["dug-in-1", "dug-in-2"]
    terrain = rig.stack.planner.terrain
    for mark in marks:
        assert terrain.obstacles[int(mark["y"] / terrain.resolution_m), int(mark["x"] / terrain.resolution_m)]
    (_t, replanned), _second = rig.events("recovery.replanned")
    assert "marked dug-in-1" in replanned["detail"] and "planning the goal again" in replanned["detail"]
    # Past the count it holds, latched, for the operator: no more backing out, said once.
    rig.run_for(2 * WINDOW_S)
    assert rig.stack.safety_mode.value == "HOLD" and NO_PROGRESS in rig.stack.safety.faults
    assert _recovery_kinds(rig)[-1] == "recovery.gave_up" and len(rig.events("recovery.gave_up")) == 1


def test_a_resume_gives_the_count_back(rig: Rig, monkeypatch: pytest.MonkeyPatch) -> None:
    DugIn(rig, monkeypatch)
    rig.run_until(lambda: bool(rig.events("recovery.gave_up")), 40.0, "the recoveries given up")
    rig.stack.resume("operator")
    rig.run_until(
        lambda: len(rig.events("recovery.backing_out")) == 3, 2 * WINDOW_S + 2.0, "a third back-out"
    )
    (_t, third) = rig.events("recovery.backing_out")[-1]
    assert "recovery 1 of 2 since the last goal given or resume" in third["detail"]


def test_a_new_goal_gives_the_count_back(rig: Rig, monkeypatch: pytest.MonkeyPatch) -> None:
    DugIn(rig, monkeypatch)
    rig.run_until(lambda: bool(rig.events("recovery.gave_up")), 40.0, "the recoveries given up")
    rig.stack.set_goal(3.0, 17.0)
    rig.run_until(
        lambda: len(rig.events("recovery.backing_out")) == 3, 2 * WINDOW_S + 4.0, "a third back-out"
    )
    assert "recovery 1 of 2" in rig.events("recovery.backing_out")[-1][1]["detail"]


def test_off_it_holds_as_before(make_rig: Callable[..., Rig], monkeypatch: pytest.MonkeyPatch) -> None:
    rig = make_rig(recover_when_stuck=False)
    DugIn(rig, monkeypatch)
    rig.run_until(lambda: bool(rig.events("failsafe.no_progress")), 20.0, "the hold")
    rig.run_for(2 * WINDOW_S)
    assert _recovery_kinds(rig) == ["failsafe.no_progress"]
    assert rig.stack.safety_mode.value == "HOLD" and rig.stack.mode is Mode.DRIVING
    assert not rig.stack.planner.terrain.obstacles.any()


def test_learning_goes_first_where_it_applies(rig: Rig, monkeypatch: pytest.MonkeyPatch) -> None:
    """A hold the learning explains (here: the first, which the stand-in clears as learning does) is not
    recovered from; one it does not explain (the second) is."""
    stack = rig.stack
    holds: list[int] = []

    def learns(pose: object, faults: tuple[str, ...]) -> None:
        holds.append(rig.now_ns)
        if len(holds) == 1:
            stack.safety.progress_learned("learned (a stand-in)")

    monkeypatch.setattr(stack, "_learn_from_digging_in", learns)
    DugIn(rig, monkeypatch)
    rig.run_until(lambda: bool(rig.events("recovery.backing_out")), 20.0, "a back-out")
    assert _recovery_kinds(rig) == [
        "failsafe.no_progress",
        "cleared.no_progress",  # learned: driving on, no back-out
        "failsafe.no_progress",
        "recovery.backing_out",  # the learning's turn came first, and it did not take
        "cleared.no_progress",
    ]
    assert holds[-1] == rig.events("recovery.backing_out")[0][0]


@pytest.mark.parametrize("why", ["tipping", "blocked", "yielding"])
def test_never_while_tipping_or_stopped_for_a_mover(
    rig: Rig, monkeypatch: pytest.MonkeyPatch, why: str
) -> None:
    """Held while a tip-over margin is breached, or while guidance is BLOCKED or YIELDING for a moving
    obstacle (a second of ticks, each shown so): no back-out; it comes once that has passed."""
    stack = rig.stack
    DugIn(rig, monkeypatch)
    consider = stack._recovery.consider
    asked: list[int] = []

    def so(now: int, pose: Any, faults: tuple[str, ...]) -> None:
        asked.append(now)
        if len(asked) >= 50:
            consider(now, pose, faults)
        elif why == "tipping":
            consider(now, pose, (*faults, TIP_OVER))
        else:
            mode, stack.guidance.mode = stack.guidance.mode, Mode(why.upper())
            consider(now, pose, faults)
            stack.guidance.mode = mode

    monkeypatch.setattr(stack._recovery, "consider", so)
    rig.run_until(lambda: len(asked) == 49, 20.0, "a second of the hold")
    assert not rig.events("recovery.backing_out") and stack.safety_mode.value == "HOLD"
    rig.run_until(lambda: bool(rig.events("recovery.backing_out")), 0.1, "a back-out once that has passed")


@pytest.mark.parametrize("why", ["at the goal", "no clear way back", "no backing out"])
def test_it_holds_with_recovery_gave_up_where_it_cannot_recover(
    make_rig: Callable[..., Rig], monkeypatch: pytest.MonkeyPatch, why: str
) -> None:
    """Dug in with the goal under the spot (a mark would make it unreachable), with the map's obstacles just
    behind it, or with backing turned off: no back-out; it holds, told once."""
    rig = make_rig(yield_speed_mps=0.0) if why == "no backing out" else make_rig()
    stack = rig.stack
    DugIn(rig, monkeypatch)
    consider = stack._recovery.consider

    def so(now: int, pose: Any, faults: tuple[str, ...]) -> None:
        if why == "at the goal":  # the goal where the front axle stands
            stack.guidance.goal = Goal(pose.x + 0.35 * math.cos(pose.yaw), pose.y + 0.35 * math.sin(pose.yaw))
        elif why == "no clear way back":  # a wall 1 m behind the rover's centre
            behind = disc_mask(
                stack.planner.terrain, pose.x - math.cos(pose.yaw), pose.y - math.sin(pose.yaw), 0.3
            )
            stack.planner.update_obstacles(behind)
        consider(now, pose, faults)

    monkeypatch.setattr(stack._recovery, "consider", so)
    rig.run_until(lambda: bool(rig.events("failsafe.no_progress")), 20.0, "the hold")
    rig.run_for(1.0)
    assert _recovery_kinds(rig) == ["failsafe.no_progress", "recovery.gave_up"]
    assert why in rig.events("recovery.gave_up")[0][1]["detail"] and stack.safety_mode.value == "HOLD"


def test_an_estop_ends_the_back_out_where_the_rover_is(rig: Rig, monkeypatch: pytest.MonkeyPatch) -> None:
    """Held by another failsafe, the back-out's clock would run on, and a resume would reverse at once:
    the back-out ends where the rover stands, said, and after the resume the rover drives its new path."""
    dug_in = DugIn(rig, monkeypatch)
    rig.run_until(lambda: rig.stack.mode is Mode.RECOVERING, 20.0, "a back-out")
    rig.run_for(0.5)
    rig.stack.estop("operator")
    rig.run_until(lambda: bool(rig.events("recovery.replanned")), 1.0, "the back-out's end")
    (_t, ended) = rig.events("recovery.replanned")[-1]
    assert ended["detail"].startswith("held (estop)")
    assert rig.stack.mode is not Mode.RECOVERING
    dug_in.on = False
    rig.stack.resume("operator")
    rig.run_for(2.0)
    states = [m for topic, _t, m in rig.sink.records if topic == "navigator/state"]
    assert states[-1]["mode"] == "DRIVING" and states[-1]["target_speed_mps"] > 0.0
    assert len(rig.events("recovery.backing_out")) == 1
