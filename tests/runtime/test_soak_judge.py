"""The soak's judgement of one fault from the rover's safety events."""

from __future__ import annotations

from hil.soak_plan import FAILSAFE, SoakFault
from hil.soak_report import NS, _judge_fault

FAULT = SoakFault("vesc", "off", 10.0, 1.5, FAILSAFE, "wheel_silent", controller=4)
WINDOW = (10.0 * NS, 11.5 * NS)  # injected, cleared (ns on the clock; epoch 0)


def _judge(events: list[tuple[int, str]]) -> tuple[bool, bool, str]:
    result = _judge_fault(FAULT, WINDOW, events, [], 0.0)
    return result.seen, result.recovered, result.evidence


def test_a_failsafe_raised_in_the_window_and_cleared_after_is_seen_and_recovered() -> None:
    events = [(int(10.3 * NS), "failsafe.wheel_silent"), (int(11.6 * NS), "cleared.wheel_silent")]
    seen, recovered, evidence = _judge(events)
    assert seen and recovered and "0.30 s after the start" in evidence


def test_a_failsafe_already_holding_when_the_fault_began_counts_as_seen() -> None:
    # A stall of the whole peer raised it just before the controller went off; it held through the start.
    events = [(int(9.8 * NS), "failsafe.wheel_silent"), (int(11.7 * NS), "cleared.wheel_silent")]
    seen, recovered, evidence = _judge(events)
    assert seen and recovered and "0.20 s before the start" in evidence


def test_a_failsafe_cleared_before_the_fault_began_does_not_count() -> None:
    events = [(int(9.0 * NS), "failsafe.wheel_silent"), (int(9.5 * NS), "cleared.wheel_silent")]
    assert _judge(events) == (False, False, "no failsafe.wheel_silent")


def test_another_failsafe_does_not_count() -> None:
    events = [(int(10.3 * NS), "failsafe.gps_lost"), (int(11.6 * NS), "cleared.gps_lost")]
    assert _judge(events)[0] is False
