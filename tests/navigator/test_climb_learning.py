"""Learning from digging in (navigator.climb_learning): the class's believed friction puts the slope the
rover dug in on just past the planner's limit (its margin off), only ever lower; only a climb the map shows,
the AHRS agreeing, with turning wheels, counts; a guidance on the new beliefs takes over what the old knew."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navigator.climb_learning import LEARN_BELOW_RAD, learned_class, trustworthy_dig_in, with_learned
from navigator.config import PlannerConfig
from navigator.follower import FollowerConfig
from navigator.guidance import Guidance
from navigator.perception import ObstacleObservation
from navigator.terrain import TerrainMap
from navigator.terrain_classes import SANDY, TERRAIN_CLASSES
from navigator.vehicle import VehicleParams, max_climbable_slope_rad

SAND = TERRAIN_CLASSES[SANDY]
MARGIN = math.radians(3.0)  # the planner's climb margin (navigator.costs.CostModel)
TURNING = (0.8,) * 6


def test_the_planner_now_stops_just_below_the_slope_it_dug_in_on() -> None:
    slope = math.radians(9.4)
    learned = learned_class(SAND, slope, MARGIN)
    assert learned is not None
    plans_to = max_climbable_slope_rad(learned.friction_mu, learned.rolling_resistance, MARGIN)
    assert plans_to == pytest.approx(slope - LEARN_BELOW_RAD, abs=1e-12)
    assert learned.friction_mu < SAND.friction_mu
    assert (learned.rolling_resistance, learned.cost_factor) == (SAND.rolling_resistance, SAND.cost_factor)
    assert "learned" in learned.source


def test_nothing_is_learned_that_would_not_lower_the_belief_or_would_forbid_every_slope() -> None:
    believed_plans_to = max_climbable_slope_rad(SAND.friction_mu, SAND.rolling_resistance, MARGIN)
    # The new limit would be at or above the believed one: nothing learned.
    assert learned_class(SAND, believed_plans_to + LEARN_BELOW_RAD, MARGIN) is None
    assert learned_class(SAND, believed_plans_to + LEARN_BELOW_RAD - 1e-3, MARGIN) is not None
    # Within a degree of level: the class would get no climb at all.
    assert learned_class(SAND, math.radians(0.9), MARGIN) is None


def test_only_the_class_dug_in_on_changes() -> None:
    learned = learned_class(SAND, math.radians(9.4), MARGIN)
    assert learned is not None
    classes = with_learned(TERRAIN_CLASSES, SANDY, learned)
    assert classes[SANDY] is learned
    assert all(classes[k] is v for k, v in TERRAIN_CLASSES.items() if k != SANDY)


ON_SLOPE = (9.4, 9.4, 9.4)
AT_FOOT = (0.0, 5.5, 11.0)  # rear axle on the flat, front on the flank: the body between


@pytest.mark.parametrize(
    ("ahrs_deg", "map_deg", "commanded", "wheels", "expected"),
    [
        (9.4, ON_SLOPE, 0.7, TURNING, True),  # nose up on the map's slope, driving on, wheels spinning
        (9.4, AT_FOOT, 0.7, TURNING, True),  # at the foot: within the span of its axles' pitches
        (-9.4, (-9.4,) * 3, -0.7, TURNING, True),  # backing up a slope
        (-9.4, (-9.4,) * 3, 0.7, TURNING, False),  # driving downhill: not a climb its grip failed
        (25.0, ON_SLOPE, 0.7, TURNING, False),  # a rock under the nose: the pitch is not the map's slope
        (9.4, (0.0, 0.0, 0.0), 0.7, TURNING, False),  # a slope the map does not show
        (9.4, ON_SLOPE, 0.7, (0.0,) * 6, False),  # wheels not turning: held by something, or stalled
        (9.4, ON_SLOPE, 0.7, (math.nan,) * 6, False),  # no wheel reports: nothing to go on
    ],
)
def test_only_a_climb_the_map_shows_with_turning_wheels_counts(
    ahrs_deg: float, map_deg: tuple[float, ...], commanded: float, wheels: tuple[float, ...], expected: bool
) -> None:
    pitches = tuple(math.radians(d) for d in map_deg)
    assert trustworthy_dig_in(math.radians(ahrs_deg), pitches, commanded, wheels) is expected


def test_a_guidance_on_new_beliefs_takes_over_every_obstacle_the_old_one_knew_however_far() -> None:
    size = (80, 200)
    terrain = TerrainMap(np.zeros(size), np.zeros(size, np.uint8), np.zeros(size, bool), 0.25)
    old = Guidance(terrain, VehicleParams(), PlannerConfig(sensing_range_m=8.0), FollowerConfig())
    old.set_goal(45.0, 10.0)
    old.observe(
        [ObstacleObservation(0, "near", 6.0, 14.0, 0.5), ObstacleObservation(0, "far", 40.0, 14.0, 0.5)]
    )
    old.update(0, 2.0, 10.0, 0.0, 0.0)  # "near" goes into the map; "far" waits until in sensing range
    old.limit_speed(0.4)
    new = Guidance(
        terrain, VehicleParams(), PlannerConfig(sensing_range_m=8.0), FollowerConfig(), TERRAIN_CLASSES
    )
    new.take_over_from(old)
    assert np.array_equal(new.planner.terrain.obstacles, old.planner.terrain.obstacles)
    assert new.planner.terrain.obstacles.any()
    assert new.mission_speed_mps == 0.4
    new.set_goal(45.0, 10.0)
    new.update(1, 38.0, 10.0, 0.0, 0.0)  # now within range of "far": it goes in too
    assert new.planner.terrain.obstacles.sum() > old.planner.terrain.obstacles.sum()
