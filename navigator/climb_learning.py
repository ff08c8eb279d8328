"""Learning from digging in: a climb the rover could not make tells it its ground's traction.

When the ``no_progress`` failsafe holds a rover whose wheels keep turning while it points uphill, the
ground under it could not carry that climb: by the planner's own law, ``tan(pitch) > mu - crr`` there. The
planner believed otherwise (it routed the rover up that slope), so its belief of that class's
``friction_mu`` was too high. It now believes the class climbs a little less than the slope it dug in on,
``mu = crr + LEARN_MARGIN tan(pitch)``, and plans again: it goes round every slope of that class as steep,
not only this one (a dune of sand is not passable a metre to the left). Only ever downward, and at most
``MAX_LEARNINGS_PER_GOAL`` times per goal: past that the rover holds, as before, for the operator.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

from navigator.terrain_classes import TerrainClass

# The slope it dug in on is believed this much past the class's new limit (tan ratio): a climb limit just
# at that slope would route it up the same flank again.
LEARN_MARGIN = 0.9
# Below this pitch the rover was not climbing: its holding there says nothing about the ground's grip.
MIN_CLIMB_RAD = math.radians(2.0)
# A rover whose wheels turn slower than this (mean of the reports, m/s) is held, not slipping.
MIN_WHEEL_SPEED_MPS = 0.1
MAX_LEARNINGS_PER_GOAL = 2


def learned_class(believed: TerrainClass, pitch_rad: float) -> TerrainClass | None:
    """``believed`` with the ``friction_mu`` that puts ``|pitch_rad|`` past its climb limit, or None when
    it already did (nothing to learn: the planner did not route it there for its grip)."""
    mu = believed.rolling_resistance + LEARN_MARGIN * math.tan(abs(pitch_rad))
    if not mu < believed.friction_mu:
        return None
    return dataclasses.replace(
        believed,
        friction_mu=mu,
        source=f"friction_mu learned digging in on {math.degrees(abs(pitch_rad)):.1f} deg; {believed.source}",
    )


def dug_in_climbing(pitch_rad: float, commanded_mps: float, wheel_speeds_mps: tuple[float, ...]) -> bool:
    """Whether a rover held for no progress was climbing with its wheels turning: slipping on a slope its
    ground could not carry, not held by an obstacle or a stall."""
    known = [abs(v) for v in wheel_speeds_mps if math.isfinite(v)]
    turning = bool(known) and sum(known) / len(known) >= MIN_WHEEL_SPEED_MPS
    climbing = abs(pitch_rad) >= MIN_CLIMB_RAD and pitch_rad * commanded_mps > 0.0
    return turning and climbing


def with_learned(
    classes: Mapping[int, TerrainClass], class_id: int, learned: TerrainClass
) -> dict[int, TerrainClass]:
    return {key: (learned if key == class_id else spec) for key, spec in classes.items()}
