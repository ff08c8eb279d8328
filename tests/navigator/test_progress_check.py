"""The ``no_progress`` failsafe: pushed for a window, a rover whose estimated position goes nowhere holds,
through GPS-like noise; one that creeps on, a stationary one not pushed, and a config with it off do not."""

from __future__ import annotations

import math
from collections.abc import Callable

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
    seconds: float,
    speed_mps: float,
    sent_mps: float = 0.5,
    config: SafetyConfig | None = None,
    seed: int = 1,
    *,
    supervisor: SafetySupervisor | None = None,
    first_tick: int = 1,
    wander: Callable[[float], float] | None = None,
    slow_every_s: float = 0.0,
) -> tuple[SafetySupervisor, list[tuple[str, str, str]]]:
    """Ticks of a rover commanded ``sent_mps`` that moves at ``speed_mps`` along x, its estimate noisy
    (white, and ``wander(t)`` m more along x); a 0 m/s command one tick in every ``slow_every_s``."""
    rng = np.random.default_rng(seed)
    events: list[tuple[str, str, str]] = []
    if supervisor is None:
        config = config or SafetyConfig()
        supervisor = SafetySupervisor(config, VehicleParams(), 0, lambda *e: events.append(e))
    slow_every = round(slow_every_s * 1e9 / TICK_NS)
    for k in range(first_tick, first_tick + round(seconds * 1e9 / TICK_NS)):
        t_s = k * TICK_NS / 1e9
        x = 5.0 + speed_mps * t_s + rng.normal(0.0, NOISE_M) + (wander(t_s) if wander else 0.0)
        y = 5.0 + rng.normal(0.0, NOISE_M)
        sent = 0.0 if slow_every and k % slow_every == 0 else sent_mps
        supervisor.update(_inputs(k * TICK_NS, sent_speed_mps=sent, position_xy=(x, y)), True)
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


@pytest.mark.parametrize("clear", ["new_goal", "resume"])
def test_a_new_goal_or_a_resume_clears_it_and_the_window_starts_again(clear: str) -> None:
    supervisor, _ = drive(12.0, 0.0)
    assert supervisor.faults == (NO_PROGRESS,)
    getattr(supervisor, clear)(*(("test",) if clear == "resume" else ()))
    assert NO_PROGRESS not in supervisor.faults
    # Dug in for 9 s, then told again: the 9 s were toward the old goal; 9 s more are not a window.
    supervisor, _ = drive(9.0, 0.0)
    getattr(supervisor, clear)(*(("test",) if clear == "resume" else ()))
    drive(9.0, 0.0, supervisor=supervisor, first_tick=451)
    assert NO_PROGRESS not in supervisor.faults
    drive(2.0, 0.0, supervisor=supervisor, first_tick=901)
    assert supervisor.faults == (NO_PROGRESS,)


def test_a_slow_tick_now_and_then_pauses_the_window_rather_than_starting_it_again() -> None:
    # A turn on the spot or a wheel's retry every 5 s must not keep a rover that is dug in from being judged.
    supervisor, _ = drive(15.0, 0.0, slow_every_s=5.0)
    assert supervisor.faults == (NO_PROGRESS,)


def test_unpushed_for_longer_than_the_pause_starts_the_window_again() -> None:
    supervisor, _ = drive(8.0, 0.0)
    drive(3.0, 0.0, sent_mps=0.0, supervisor=supervisor, first_tick=401)  # BLOCKED for 3 s
    drive(8.0, 0.0, supervisor=supervisor, first_tick=551)
    assert NO_PROGRESS not in supervisor.faults  # 8 + 8 s pushed, but not 10 in a row


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_an_estimate_wandering_slowly_does_not_hide_or_fake_progress_at_two_tenths(seed: int) -> None:
    # The estimate off by up to 0.5 m over 16 s (GPS and slipping odometry, as at the dune's foot): 0.2 m/s
    # is 2 m in a window, four times the radius, and is progress; going nowhere is not.
    def wander(t_s: float) -> float:
        return 0.5 * math.sin(2.0 * math.pi * t_s / 16.0 + seed)

    moving, _ = drive(40.0, 0.2, seed=seed, wander=wander)
    assert NO_PROGRESS not in moving.faults
    stuck, _ = drive(40.0, 0.0, seed=seed, wander=wander)
    assert stuck.faults == (NO_PROGRESS,)


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
    # Buckets of 25 ticks close on ticks 26, 51, ...: the 20th (10 s) on tick 501.
    answers = [check.update(k * TICK_NS, 0.0, 0.0) for k in range(1, 501)]
    assert all(answer is None for answer in answers)
    assert check.update(501 * TICK_NS, math.nan, 0.0) is None  # not a position: no answer, nothing closed
    assert check.update(502 * TICK_NS, 0.0, 0.0) == 0.0  # a whole window, the bucket closing now
    assert check.update(503 * TICK_NS, 0.0, 0.0) is None  # between closings: nothing new to say
