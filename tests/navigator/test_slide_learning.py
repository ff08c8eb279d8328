"""Learning from sliding sideways (navigator.slide_learning): a whole window of GPS ground velocity
downhill across the heading, past the threshold, on one class, the AHRS roll the map's, driving at speed
and not tipping, is a slide; the noise the simulated rover shows without sliding, drift uphill, a roll the map
lacks, two classes, tipping or a slow rover are not."""

from __future__ import annotations

import math

import numpy as np
import pytest

from logs.clock import NS_PER_S
from navigator.climb_learning import learned_class
from navigator.slide_learning import (
    SLIDE_MPS,
    WINDOW_NS,
    Slide,
    SlideSample,
    SlideWatch,
    across_heading_mps,
    downhill_mps,
    routed_across,
    slide_evidence,
    trustworthy_roll,
)
from navigator.terrain_classes import TERRAIN_CLASSES

TICK_NS = NS_PER_S // 50  # the stack's control tick
SANDY = 2
MARGIN = math.radians(3.0)  # the planner's climb margin (navigator.costs.CostModel)
ROLL = math.radians(12.0)  # ground rising to the left: downhill is to the right
MAP_ROLLS = (ROLL, ROLL, ROLL)
HEADING = math.radians(30.0)


def _course(downhill: float, speed: float = 1.0) -> tuple[float, float]:
    """The GPS's (speed, course) of a rover driving ``speed`` along ``HEADING`` and sliding ``downhill``
    m/s to its right (the downhill side of ``ROLL``)."""
    return math.hypot(speed, downhill), HEADING - math.atan2(downhill, speed)


def _evidence(
    downhill: float = 0.3,
    *,
    speed: float = 1.0,
    yaw_rate: float = 0.0,
    heading_std: float = math.radians(1.0),
    tipping: bool = False,
    gps_age_ns: int = 0,
    ahrs_roll: float = ROLL,
    map_rolls: tuple[float, ...] = MAP_ROLLS,
    classes: tuple[int, ...] = (SANDY, SANDY, SANDY),
) -> SlideSample | None:
    return slide_evidence(
        speed,
        yaw_rate,
        heading_std,
        tipping,
        gps_age_ns,
        _course(downhill, speed),
        HEADING,
        ahrs_roll,
        map_rolls,
        classes,
    )


def _run(watch: SlideWatch, samples: list[SlideSample | None]) -> list[tuple[int, Slide]]:
    found = []
    for tick, sample in enumerate(samples):
        slide = watch.feed(tick * TICK_NS, sample)
        if slide is not None:
            found.append((tick * TICK_NS, slide))
    return found


def test_the_velocity_across_the_heading_is_signed_left_and_downhill_by_the_roll() -> None:
    assert across_heading_mps(1.0, math.radians(10.0), 0.0) == pytest.approx(math.sin(math.radians(10.0)))
    assert across_heading_mps(1.0, HEADING, HEADING) == 0.0
    assert downhill_mps(-0.2, ROLL) == 0.2  # to the right, the roll's low side
    assert downhill_mps(-0.2, -ROLL) == -0.2  # the ground rising to the right: that was uphill
    assert downhill_mps(0.2, 0.0) == 0.0
    sample = _evidence(0.3)
    assert sample is not None and sample.downhill_mps == pytest.approx(0.3, abs=1e-12)


def test_a_whole_window_sliding_downhill_past_the_threshold_is_one_slide() -> None:
    watch = SlideWatch()
    sample = _evidence(0.2)
    found = _run(watch, [sample] * (3 * WINDOW_NS // TICK_NS))
    # At the window's end, once; then the window starts again (one more window fits in the run).
    assert [t for t, _s in found] == [WINDOW_NS, 2 * WINDOW_NS + TICK_NS]
    slide = found[0][1]
    assert slide.downhill_mps == pytest.approx(0.2) and slide.roll_rad == pytest.approx(ROLL)
    assert slide.class_id == SANDY


def test_just_below_the_threshold_or_a_window_cut_short_is_nothing() -> None:
    below = SLIDE_MPS - 0.005
    assert _run(SlideWatch(), [_evidence(below)] * (5 * WINDOW_NS // TICK_NS)) == []
    # A tick without evidence (a fix gone stale) in every window: it never covers one.
    gap = [*([_evidence(0.5)] * (WINDOW_NS // TICK_NS - 1)), None]
    assert _run(SlideWatch(), gap * 5) == []


def test_the_noise_the_rover_shows_without_sliding_is_nothing() -> None:
    # The simulated rover driving without a slide (docs/planning.md: default, sandy, hills, rocky, muddy,
    # carts, maze): per tick up to 0.15 m/s (rms up to 0.05), its 2 s means up to 0.08 m/s. Here white
    # noise of that rms on a bias of the worst mean, seeded, for ten minutes of ticks.
    rng = np.random.default_rng(7)
    ticks = 600 * NS_PER_S // TICK_NS
    noise = 0.08 + rng.normal(0.0, 0.05, ticks)
    samples = [_evidence(float(n)) for n in noise]
    assert _run(SlideWatch(), samples) == []
    # The same noise on a slide of twice the threshold: every window seen.
    sliding = [_evidence(float(n) - 0.08 + 2 * SLIDE_MPS) for n in noise]
    assert len(_run(SlideWatch(), sliding)) == ticks // (WINDOW_NS // TICK_NS + 1)


def test_drift_uphill_is_nothing() -> None:
    assert _run(SlideWatch(), [_evidence(-0.4)] * (3 * WINDOW_NS // TICK_NS)) == []


@pytest.mark.parametrize(
    ("ahrs_deg", "map_deg", "trusted"),
    [
        (12.0, (12.0, 12.0, 12.0), True),
        (13.9, (11.0, 12.0, 12.0), True),  # within 2 deg of the span under the axles
        (14.5, (12.0, 12.0, 12.0), False),  # steeper than the map: a rock under a wheel, sinking
        (12.0, (0.0, 0.0, 0.0), False),  # a roll the map lacks
        (0.8, (0.8, 0.8, 0.8), False),  # within a degree of level: nothing to learn
    ],
)
def test_the_roll_must_be_the_maps(ahrs_deg: float, map_deg: tuple[float, ...], trusted: bool) -> None:
    ahrs, rolls = math.radians(ahrs_deg), tuple(math.radians(d) for d in map_deg)
    assert trustworthy_roll(ahrs, rolls) is trusted
    assert (_evidence(0.5, ahrs_roll=ahrs, map_rolls=rolls) is not None) is trusted


def test_two_classes_tipping_a_slow_rover_or_a_stale_fix_show_nothing() -> None:
    assert _evidence(0.5, classes=(SANDY, SANDY, 0)) is None
    assert _evidence(0.5, tipping=True) is None
    assert _evidence(0.5, speed=0.25) is None
    assert _evidence(0.5, gps_age_ns=NS_PER_S) is None
    assert _evidence(0.5, speed=0.3) is not None
    # Alternating classes never make a window: each change starts it again.
    other = SlideSample(0.5, ROLL, 0)
    assert _run(SlideWatch(), [_evidence(0.5), other] * (2 * WINDOW_NS // TICK_NS)) == []


def test_a_watch_needs_a_window_and_a_threshold() -> None:
    with pytest.raises(ValueError, match="window"):
        SlideWatch(0, SLIDE_MPS)
    with pytest.raises(ValueError, match="threshold"):
        SlideWatch(WINDOW_NS, math.nan)


def test_a_slide_on_a_slope_the_belief_already_keeps_routes_off_says_nothing_new() -> None:
    sand = TERRAIN_CLASSES[SANDY]  # the table's: the planner routes up to 12.6 deg
    slide = Slide(0.3, ROLL, SANDY)
    assert routed_across(slide, sand, MARGIN)
    learned = learned_class(sand, ROLL, MARGIN)  # now it stops a degree below: 11 deg
    assert learned is not None and not routed_across(slide, learned, MARGIN)
    # Leaving the slope after learning, it slides on: a roll a little off gives no second learning.
    assert not routed_across(Slide(0.3, ROLL - math.radians(0.5), SANDY), learned, MARGIN)
    assert not routed_across(Slide(0.3, -ROLL, SANDY), learned, MARGIN)  # either side


@pytest.mark.parametrize(
    ("changes", "counts"),
    [
        ({}, True),
        ({"yaw_rate": 0.2}, False),  # turning: the fix's course lags the heading (a delayed GPS in a turn)
        ({"yaw_rate": -0.1}, True),
        ({"heading_std": math.radians(5.0)}, False),  # 1 m/s x sin(10 deg) = 0.17 m/s: no slide to tell
        ({"heading_std": math.radians(2.0)}, True),  # 1 m/s x sin(4 deg) = 0.07 m/s
    ],
    ids=["straight", "turning", "gentle-turn", "heading-unsure", "heading-known"],
)
def test_a_turn_or_an_unsure_heading_is_no_evidence(changes: dict[str, float], counts: bool) -> None:
    yaw_rate, heading_std = changes.get("yaw_rate", 0.0), changes.get("heading_std", math.radians(1.0))
    assert (_evidence(0.3, yaw_rate=yaw_rate, heading_std=heading_std) is not None) is counts


def test_a_gap_in_the_ticks_starts_the_window_again() -> None:
    """One tick, then a tick 5 s later (the watch not fed in between: a hold, a stalled loop) is not 2 s of
    unbroken evidence."""
    watch = SlideWatch()
    sample = _evidence(0.3)
    assert watch.feed(0, sample) is None
    assert watch.feed(5 * WINDOW_NS, sample) is None
