"""The supervisor's wheel checks skip their per-wheel work on the common ticks (every wheel heard recently;
no wheel commanded, or every wheel turning): the wheels those shortcuts must not hide still trip."""

from __future__ import annotations

import math
from typing import Any

import pytest

from navigator.safety import SafetyInputs, SafetySupervisor
from navigator.safety_config import SafetyConfig
from navigator.vehicle import VehicleParams
from tests.runtime.test_supervisor import inputs

TICK_NS = 20_000_000


def _inputs(now_ns: int, **changes: Any) -> SafetyInputs:
    """A calm driving tick (the supervisor tests' inputs, every wheel commanded and turning), changed."""
    calm = inputs(now_ns, (5.0, 5.0))._replace(
        sent_speed_mps=0.5,
        sent_at_ns=0,
        measured_speed_mps=0.5,
        wheel_commands_mps=(0.5,) * 6,
        wheel_speeds_mps=(0.5,) * 6,
        wheel_currents_a=(5.0,) * 6,
    )
    return calm._replace(**changes)


def _faults_after(ticks: int, **changes: Any) -> tuple[str, ...]:
    supervisor = SafetySupervisor(SafetyConfig(), VehicleParams(), 0, lambda *event: None)
    decision = None
    for k in range(1, ticks + 1):
        decision = supervisor.update(_inputs(k * TICK_NS, **changes), True)
    assert decision is not None
    return decision.faults


def test_calm_ticks_trip_nothing() -> None:
    assert _faults_after(100) == ()


@pytest.mark.parametrize("stalled", [0, 2, 5])
def test_one_stalled_wheel_among_turning_ones_trips(stalled: int) -> None:
    speeds = tuple(0.0 if index == stalled else 0.5 for index in range(6))
    assert _faults_after(60, wheel_speeds_mps=speeds) == ("wheel_stalled",)


@pytest.mark.parametrize("first", [True, False])
def test_a_nan_speed_is_judged_wheel_by_wheel(first: bool) -> None:
    # NaN is no stall evidence for its own wheel, and must not hide a stalled one elsewhere.
    speeds = (math.nan, 0.5, 0.0, 0.5, 0.5, 0.5) if first else (0.5, math.nan, 0.0, 0.5, 0.5, 0.5)
    assert _faults_after(60, wheel_speeds_mps=speeds) == ("wheel_stalled",)


def test_one_wheel_commanded_among_idle_ones_can_trip() -> None:
    commands = (0.0, 0.0, 0.5, 0.0, 0.0, 0.0)
    assert _faults_after(60, wheel_commands_mps=commands, wheel_speeds_mps=(0.0,) * 6) == ("wheel_stalled",)


def test_stopped_wheels_are_not_stalled() -> None:
    assert _faults_after(60, wheel_commands_mps=(0.0,) * 6, wheel_speeds_mps=(0.0,) * 6) == ()


@pytest.mark.parametrize("statuses", ["one_old", "one_never"])
def test_one_silent_wheel_among_fresh_ones_trips(statuses: str) -> None:
    supervisor = SafetySupervisor(SafetyConfig(), VehicleParams(), 0, lambda *event: None)
    now = 20 * TICK_NS  # 0.4 s: past wheel_silent_s (0.25 s) since the start and since t = 0
    stale: int | None = 0 if statuses == "one_old" else None
    decision = supervisor.update(_inputs(now, wheel_last_status_ns=(now, now, stale, now, now, now)), True)
    assert decision.faults == ("wheel_silent",)


def _battery_run(voltages: list[float | None], *, forced: bool) -> tuple[list[Any], list[Any]]:
    events: list[tuple[str, str, str]] = []
    supervisor = SafetySupervisor(SafetyConfig(), VehicleParams(), 0, lambda *event: events.append(event))
    if forced:
        supervisor._battery_floor_v = math.inf  # never the shortcut: the full check on every tick
    decisions = [
        supervisor.update(_inputs(k * TICK_NS, battery_v=v), True) for k, v in enumerate(voltages, start=1)
    ]
    return events, decisions


def test_the_battery_shortcut_judges_as_the_full_check() -> None:
    """Above both thresholds (or with no reading) the battery check only drops its timers; a supervisor
    forced through the full check on every tick must report the same events and decisions."""
    # Around both thresholds: sags, sustained lows, recoveries through the hysteresis, no readings between.
    levels = [24.0, 20.9, 21.05, 19.5, 20.1, 20.35, 21.2, 21.4, 0.0, math.nan, 19.0, 21.5, 22.0]
    voltages: list[float | None] = [None]
    for level in levels:
        voltages += [level] * 150  # 3 s each: past battery_debounce_s
    voltages += [None] * 10 + [19.5] * 5 + [24.0] * 5
    events, decisions = _battery_run(voltages, forced=False)
    assert (events, decisions) == _battery_run(voltages, forced=True)
    kinds = {kind for kind, _, _ in events}
    assert {"failsafe.battery_low", "failsafe.battery_critical", "cleared.battery_low"} <= kinds
    assert "cleared.battery_critical" in kinds
