"""A slow start-up is nobody's silence: the link budgets count from the loop's first tick.

On a cold numba cache (a fresh clone) the warm-up compiles for ~15 s, and a HIL peer or an autopilot on
``udpin`` says nothing until our first heartbeat, which goes out on the first tick. The links and the
supervisor were built before the warm-up, so the first tick found every budget long spent and raised
``gps_lost``, ``heartbeat_lost``, ``wheel_silent`` (and the links' own ``mavlink_link_lost``) for nothing.
Here the warm-up is the real one, and the simulated clock then moves on by what compiling took.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from logs.clock import to_ns
from navigator.warm_up import warm_up
from tests.runtime.rig import MSG_ATTITUDE, MSG_GPS_RAW_INT, MSG_HEARTBEAT, Rig, rig_config
from tests.runtime.test_failsafes import assert_fired_in_window

COLD_CACHE_WARM_UP_S = 15.0


@pytest.fixture
def rig() -> Iterator[Rig]:
    made = Rig(rig_config())
    warm_up(made.stack.planner, rig_config(), made.clock)
    made.clock.advance(to_ns(COLD_CACHE_WARM_UP_S))
    yield made
    made.close()


def alarms(rig: Rig) -> list[str]:
    """Every failsafe fired and every link reported lost or silent, as ``kind: detail``."""
    return [
        f"{m['kind']}: {m['detail']}"
        for topic, _, m in rig.sink.records
        if topic == "safety/events"
        and (m["kind"].startswith("failsafe.") or m["kind"] in ("mavlink_link_lost", "can_controller_silent"))
    ]


def test_a_long_warm_up_raises_no_failsafe(rig: Rig) -> None:
    # The loop's first tick comes before the peer has said anything: it answers our first heartbeat.
    rig.stack.step()
    rig.drive()
    assert alarms(rig) == []


@pytest.mark.parametrize(
    ("silenced", "failsafe", "budget_s"),
    [
        (MSG_HEARTBEAT, "heartbeat_lost", 3.0),
        (MSG_GPS_RAW_INT, "gps_lost", 3.0),
        # Never seen counts from the first tick too: an autopilot that never streams ATTITUDE leaves the
        # tip-over check blind from the start.
        (MSG_ATTITUDE, "attitude_lost", 1.0),
    ],
)
def test_a_link_silent_from_the_start_still_fails_safe_counted_from_the_first_tick(
    rig: Rig, silenced: int, failsafe: str, budget_s: float
) -> None:
    rig.wire.dropped = {silenced}
    first_tick = rig.control_tick()
    rig.run_for(budget_s + 0.2)
    assert_fired_in_window(rig.first_event_ns(f"failsafe.{failsafe}"), first_tick, budget_s)


def test_wheel_controllers_silent_from_the_start_still_fail_safe(rig: Rig) -> None:
    rig.bus.silent_ids = {1, 2, 3, 4, 5, 6}
    first_tick = rig.control_tick()
    rig.run_for(0.5)
    assert_fired_in_window(rig.first_event_ns("failsafe.wheel_silent"), first_tick, 0.25)
    assert rig.stack.safety_mode.value == "HOLD"
