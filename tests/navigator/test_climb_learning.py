"""Learning from digging in (navigator.climb_learning): the class's believed friction puts the slope the
rover dug in on past its climb limit, only ever lower, and only for a rover climbing with turning wheels."""

from __future__ import annotations

import math

import pytest

from navigator.climb_learning import LEARN_MARGIN, dug_in_climbing, learned_class, with_learned
from navigator.terrain_classes import SANDY, TERRAIN_CLASSES
from navigator.vehicle import max_climbable_slope_rad

SAND = TERRAIN_CLASSES[SANDY]
TURNING = (0.8,) * 6


def test_the_slope_it_dug_in_on_is_past_the_learned_limit_by_the_margin() -> None:
    pitch = math.radians(9.4)
    learned = learned_class(SAND, pitch)
    assert learned is not None
    assert learned.friction_mu == pytest.approx(SAND.rolling_resistance + LEARN_MARGIN * math.tan(pitch))
    limit = max_climbable_slope_rad(learned.friction_mu, learned.rolling_resistance)
    assert math.tan(limit) == pytest.approx(LEARN_MARGIN * math.tan(pitch))
    assert limit < pitch < max_climbable_slope_rad(SAND.friction_mu, SAND.rolling_resistance)
    assert (learned.rolling_resistance, learned.cost_factor) == (SAND.rolling_resistance, SAND.cost_factor)
    assert "learned" in learned.source


def test_nothing_is_learned_where_the_belief_already_forbade_the_slope() -> None:
    steeper_than_believed = math.atan(SAND.friction_mu - SAND.rolling_resistance) + math.radians(2.0)
    assert learned_class(SAND, steeper_than_believed) is None


def test_only_the_class_dug_in_on_changes() -> None:
    learned = learned_class(SAND, math.radians(9.4))
    assert learned is not None
    classes = with_learned(TERRAIN_CLASSES, SANDY, learned)
    assert classes[SANDY] is learned
    assert all(classes[k] is v for k, v in TERRAIN_CLASSES.items() if k != SANDY)


@pytest.mark.parametrize(
    ("pitch_deg", "commanded", "wheels", "expected"),
    [
        (9.4, 0.7, TURNING, True),  # nose up, driving forward, wheels spinning: dug in climbing
        (-9.4, -0.7, TURNING, True),  # backing up a slope
        (-9.4, 0.7, TURNING, False),  # driving downhill: not a climb its grip failed
        (1.0, 0.7, TURNING, False),  # level: held for some other reason
        (9.4, 0.7, (0.0,) * 6, False),  # wheels not turning: held by something, or stalled
        (9.4, 0.7, (math.nan,) * 6, False),  # no wheel reports: nothing to go on
    ],
)
def test_only_a_climb_with_turning_wheels_counts(
    pitch_deg: float, commanded: float, wheels: tuple[float, ...], expected: bool
) -> None:
    assert dug_in_climbing(math.radians(pitch_deg), commanded, wheels) is expected
