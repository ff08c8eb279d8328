"""The ``no_progress`` failsafe: pushed for a window, a rover whose estimated position goes nowhere holds,
through GPS-like noise; one that creeps on, a stationary one not pushed, and a config with it off do not."""

from __future__ import annotations

import math

import numpy as np
import pytest

from logs.settings import ConfigError, parse_toml
from navigator.progress_check import ProgressCheck
from navigator.safety import NO_PROGRESS, SafetyMode, SafetySupervisor
from navigator.safety_config import SafetyConfig
from navigator.vehicle import VehicleParams
from tests.navigator.test_safety_common_ticks import TICK_NS, _inputs

NOISE_M = 0.3  # the estimate's wander at the dune's foot in scenarios/sand-dune.toml reached +-0.5 m


def drive(
    seconds: float, speed_mps: float, sent_mps: float = 0.5, config: SafetyConfig | None = None, seed: int = 1
) -> tuple[SafetySupervisor, list[tuple[str, str, str]]]:
    """Ticks of a rover commanded ``sent_mps`` that moves at ``speed_mps`` along x, its estimate noisy."""
    rng = np.random.default_rng(seed)
    events: list[tuple[str, str, str]] = []
    supervisor = SafetySupervisor(config or SafetyConfig(), VehicleParams(), 0, lambda *e: events.append(e))
    for k in range(1, round(seconds * 1e9 / TICK_NS) + 1):
        t_s = k * TICK_NS / 1e9
        x, y = 5.0 + speed_mps * t_s + rng.normal(0.0, NOISE_M), 5.0 + rng.normal(0.0, NOISE_M)
        supervisor.update(_inputs(k * TICK_NS, sent_speed_mps=sent_mps, position_xy=(x, y)), True)
    return supervisor, events


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_pushed_and_going_nowhere_holds_through_the_noise(seed: int) -> None:
    supervisor, events = drive(12.0, 0.0, seed=seed)
    assert supervisor.faults == (NO_PROGRESS,)
    assert supervisor.mode is SafetyMode.HOLD
    tripped = [detail for kind, _, detail in events if kind == f"failsafe.{NO_PROGRESS}"]
    assert len(tripped) == 1 and "for 10 s" in tripped[0] and "limit 0.5 m" in tripped[0]
    assert "the wheels turn at 0.50 m/s on average: slipping or dug in" in tripped[0]


def test_its_event_says_when_the_wheels_are_not_turning() -> None:
    events: list[tuple[str, str, str]] = []
    supervisor = SafetySupervisor(SafetyConfig(), VehicleParams(), 0, lambda *e: events.append(e))
    for k in range(1, 600):
        tick = _inputs(k * TICK_NS, wheel_speeds_mps=(0.0,) * 6, wheel_currents_a=(0.0,) * 6)
        supervisor.update(tick, True)
    tripped = [detail for kind, _, detail in events if kind == f"failsafe.{NO_PROGRESS}"]
    assert tripped and tripped[0].endswith("the wheels turn at 0.00 m/s on average: not turning")


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_creeping_on_at_a_tenth_of_a_metre_a_second_is_progress(seed: int) -> None:
    supervisor, _ = drive(30.0, 0.1, seed=seed)
    assert NO_PROGRESS not in supervisor.faults


def test_standing_still_unpushed_is_not_judged() -> None:
    supervisor, _ = drive(30.0, 0.0, sent_mps=0.1)  # below stuck_min_command_mps
    assert NO_PROGRESS not in supervisor.faults


def test_a_new_goal_or_a_resume_clears_it_and_the_window_starts_again() -> None:
    supervisor, _ = drive(12.0, 0.0)
    supervisor.new_goal()
    assert NO_PROGRESS not in supervisor.faults
    supervisor, _ = drive(12.0, 0.0)
    supervisor.resume("test")
    assert NO_PROGRESS not in supervisor.faults


def test_progress_time_zero_turns_it_off() -> None:
    supervisor, _ = drive(30.0, 0.0, config=SafetyConfig(progress_time_s=0.0))
    assert NO_PROGRESS not in supervisor.faults


@pytest.mark.parametrize("value", [0.5, 3.9])
def test_a_window_too_short_for_its_two_means_is_refused(value: float) -> None:
    table = parse_toml(f"[safety]\nprogress_time_s = {value}\n", "rover.toml").table("safety")
    with pytest.raises(ConfigError) as caught:
        SafetyConfig.from_table(table)
    assert caught.value.key == "safety.progress_time_s"


def test_the_check_waits_for_a_whole_window_and_skips_positions_that_are_not_numbers() -> None:
    check = ProgressCheck(10 * 10**9)
    answers = [check.update(k * TICK_NS, 0.0, 0.0) for k in range(1, 500)]
    assert all(answer is None for answer in answers)  # 9.98 s: not yet
    assert check.update(500 * TICK_NS, math.nan, 0.0) is None
    moved = None
    for k in range(501, 560):
        moved = check.update(k * TICK_NS, 0.0, 0.0)
    assert moved == 0.0
