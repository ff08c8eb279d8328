"""Learning from digging in: a climb the rover could not make tells it its ground's traction.

When the ``no_progress`` failsafe holds a rover that was driving its route uphill with its wheels turning,
the ground under it could not carry that climb: by the planner's own law, ``tan(slope) > mu - crr`` there.
The planner believed otherwise (it routed the rover up that slope), so its belief of that class's
``friction_mu`` was too high. It now believes the class climbs a little less than that slope, so the
planner (which keeps ``climb_margin`` below every class's limit) forbids it: ``mu = crr + tan(slope -
LEARN_BELOW + climb_margin)``; and plans again. It then goes round every slope of that class as steep, not
only this one (a dune of sand is not passable a metre to the left).

It learns only from what it can trust: the AHRS's pitch lies within ``PITCH_AGREEMENT`` of the map's
pitches under the rover's axles (so the slope is the ground's, one the map shows), the class is the same
under the rover's centre and its front axle, the wheels turn (slipping, not held by something) and no
tip-over margin is breached. A rock under the nose,
sinking, or a slope the map does not show gives a pitch the map does not, and the rover holds for the
operator, as it does past ``MAX_LEARNINGS_PER_GOAL`` per goal.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

from navigator.progress_check import WHEELS_TURNING_MPS, mean_wheel_speed
from navigator.terrain_classes import TerrainClass

# The learned limit is this far below the slope it dug in on (as the planner applies it, its margin off).
LEARN_BELOW_RAD = math.radians(1.0)
# The AHRS's pitch and the map's slope must agree this well: else the pitch is not the ground's slope.
PITCH_AGREEMENT_RAD = math.radians(2.0)
MAX_LEARNINGS_PER_GOAL = 2


def learned_class(believed: TerrainClass, slope_rad: float, climb_margin_rad: float) -> TerrainClass | None:
    """``believed`` with the ``friction_mu`` whose climb limit, less the planner's ``climb_margin_rad``, is
    ``LEARN_BELOW_RAD`` under ``slope_rad``; None when that would not lower the belief, or would leave the
    class no climb at all (a slope within the margin: holding there says nothing the planner can use)."""
    limit = abs(slope_rad) - LEARN_BELOW_RAD
    if limit <= 0.0:
        return None
    mu = believed.rolling_resistance + math.tan(limit + climb_margin_rad)
    if not mu < believed.friction_mu:
        return None
    return dataclasses.replace(
        believed,
        friction_mu=mu,
        source=f"friction_mu learned digging in on {math.degrees(abs(slope_rad)):.1f} deg; {believed.source}",
    )


def trustworthy_dig_in(
    ahrs_pitch_rad: float,
    map_pitches_rad: tuple[float, ...],
    commanded_mps: float,
    wheel_speeds_mps: tuple[float, ...],
) -> bool:
    """Whether a rover held for no progress dug in climbing a slope the map shows, its wheels turning:
    slipping on ground that could not carry the climb, not held by an obstacle, a stall or a bump.

    ``map_pitches_rad``: the map's pitch under the rover's axles (rear, centre, front): at the foot of a
    slope they differ, and the body's pitch lies between them; it must lie within ``PITCH_AGREEMENT_RAD``
    of that span, else it is not the ground's (a rock under the nose, sinking, a slope the map lacks)."""
    mean = mean_wheel_speed(wheel_speeds_mps)  # the no_progress event's own test of "turning"
    turning = mean is not None and mean >= WHEELS_TURNING_MPS
    low, high = min(map_pitches_rad), max(map_pitches_rad)
    agrees = low - PITCH_AGREEMENT_RAD <= ahrs_pitch_rad <= high + PITCH_AGREEMENT_RAD
    climbing = ahrs_pitch_rad * commanded_mps > 0.0
    return turning and agrees and climbing


def with_learned(
    classes: Mapping[int, TerrainClass], class_id: int, learned: TerrainClass
) -> dict[int, TerrainClass]:
    return {key: (learned if key == class_id else spec) for key, spec in classes.items()}
