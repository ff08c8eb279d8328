"""The real onboard stack's answers to goal / e-stop / resume confirm them as the ground station judges.

No Zenoh here: the stack (tests/runtime/rig.py, lockstep, simulated peers) records into memory, and every
``safety/events`` and ``navigator/state`` record after a command goes through the same ``CommandWatch``
that ``rover telemetry send`` uses. If the navigator renames an event or its e-stop reason, this fails.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from logs.command_watch import CommandWatch, Verdict
from logs.commands import CommandKind, RoverCommand
from logs.telemetry import TelemetrySample
from tests.runtime.rig import FakeGroundStation, Rig, rig_config

FENCE = ((0.0, 0.0), (20.0, 0.0), (20.0, 20.0), (0.0, 20.0))
TICKS = 5  # the stack reads commands at the start of a tick; a few ticks publish its state after
PLAN_TICKS = 200  # 10 s of 20 Hz ticks: the start-up checks (2 s of settled estimate) and the first plan
WIDE_FENCE = ((-50.0, -50.0), (50.0, -50.0), (50.0, 50.0), (-50.0, 50.0))  # the rig's map is 20 x 20 m


@pytest.fixture
def rover() -> Iterator[tuple[Rig, FakeGroundStation]]:
    ground = FakeGroundStation()
    rig = Rig(rig_config(fence=FENCE), commands=ground)
    try:
        rig.run_for(0.2)
        yield rig, ground
    finally:
        rig.close()


def _send(
    rig: Rig,
    ground: FakeGroundStation,
    kind: CommandKind,
    x: float | None = None,
    y: float | None = None,
    *,
    ticks: int = TICKS,
) -> CommandWatch:
    """Queue the command, run ``ticks`` ticks (or until the watch decides), and show the watch what the
    rover recorded meanwhile, tick by tick."""
    watch = CommandWatch(kind, x, y)
    seen = len(rig.sink.records)
    ground.queued.append(RoverCommand(kind, rig.now_ns, x, y))
    for _ in range(ticks):
        rig.control_tick()
        for topic, log_time_ns, message in rig.sink.records[seen:]:
            watch.observe(TelemetrySample(topic, log_time_ns, dict(message)))
        seen = len(rig.sink.records)
        if watch.decided.is_set():
            break
    return watch


def test_estop_then_resume_are_confirmed_by_the_stacks_own_streams(
    rover: tuple[Rig, FakeGroundStation],
) -> None:
    rig, ground = rover
    estop = _send(rig, ground, "estop")
    assert estop.outcome is not None and estop.outcome.verdict is Verdict.CONFIRMED
    assert "failsafe.estop" in estop.outcome.detail
    assert rig.stack.safety_mode.value == "ESTOP"

    # Sent again: no new event, but navigator/state still shows the e-stop, which is what was asked.
    again = _send(rig, ground, "estop")
    assert again.outcome is not None and again.outcome.verdict is Verdict.CONFIRMED
    assert "navigator/state" in again.outcome.detail and "safety estop" in again.outcome.detail

    resume = _send(rig, ground, "resume")
    assert resume.outcome is not None and resume.outcome.verdict is Verdict.CONFIRMED
    assert "cleared.estop" in resume.outcome.detail
    assert rig.stack.safety_mode.value != "ESTOP"


def test_goal_is_confirmed_by_navigator_state_and_a_fenced_off_goal_is_refused(
    rover: tuple[Rig, FakeGroundStation],
) -> None:
    rig, ground = rover
    # Taken at once, but confirmed only by the plan: after the start-up checks (a settled estimate).
    inside = _send(rig, ground, "goal", 12.25, 4.5, ticks=PLAN_TICKS)
    assert inside.outcome is not None and inside.outcome.verdict is Verdict.CONFIRMED
    assert "mode DRIVING" in inside.outcome.detail and "goal (12.25, 4.50)" in inside.outcome.detail

    outside = _send(rig, ground, "goal", 30.0, 3.0)
    assert outside.outcome is not None and outside.outcome.verdict is Verdict.REJECTED
    assert "geofence" in outside.outcome.detail
    assert rig.stack.goal is not None and (rig.stack.goal.x, rig.stack.goal.y) == (12.25, 4.5)


def test_a_goal_off_the_map_inside_the_fence_is_refused_with_the_planners_reason() -> None:
    ground = FakeGroundStation()
    rig = Rig(rig_config(fence=WIDE_FENCE), commands=ground)
    try:
        rig.run_for(0.2)
        off_map = _send(rig, ground, "goal", 30.0, 3.0, ticks=PLAN_TICKS)
        assert off_map.outcome is not None and off_map.outcome.verdict is Verdict.REJECTED
        assert "guidance.no_path" in off_map.outcome.detail, off_map.outcome.detail
        assert "goal position is not on the map" in off_map.outcome.detail, off_map.outcome.detail
        assert rig.stack.mode.value == "NO_PATH"
    finally:
        rig.close()


def test_an_estop_the_stack_never_reads_is_not_confirmed(rover: tuple[Rig, FakeGroundStation]) -> None:
    rig, _ = rover
    watch = CommandWatch("estop")
    already = len(rig.sink.records)
    for _ in range(TICKS):  # the rover keeps publishing, but nobody queued the command
        rig.control_tick()
    for topic, log_time_ns, message in rig.sink.records[already:]:
        watch.observe(TelemetrySample(topic, log_time_ns, dict(message)))
    assert watch.outcome is None and not watch.decided.is_set()
    assert watch.seen["navigator/state"] >= TICKS - 1
    assert "the last navigator/state" in watch.what_was_seen()
