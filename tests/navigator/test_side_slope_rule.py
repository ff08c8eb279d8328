"""The planner's side-slope rule: a move across a slope the rover cannot hold on sideways is forbidden."""

import math

import numpy as np
import pytest

from navigator.astar_kernel import MOVES
from navigator.direction_costs import DirectionWeights, direction_factors
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TERRAIN_CLASSES, TerrainClass
from navigator.vehicle import VehicleParams, max_climbable_slope_rad

PARAMS = VehicleParams()
MUD = TERRAIN_CLASSES[3]
MARGIN = DirectionWeights().climb_margin_rad
EAST, NORTH = MOVES.tolist().index([0, 1]), MOVES.tolist().index([1, 0])


def plane(grade_x: float, grade_y: float, class_id: int = 3, size: tuple[int, int] = (20, 20)) -> TerrainMap:
    rows, cols = size
    ys, xs = np.mgrid[0:rows, 0:cols] * 0.25
    elevation = grade_x * xs + grade_y * ys
    return TerrainMap(elevation, np.full(size, class_id, np.uint8), np.zeros(size, bool), 0.25)


def driving_limit(terrain_class: TerrainClass = MUD) -> float:
    """tan of the steepest side slope the rule lets the rover drive across along the contour."""
    crr = terrain_class.rolling_resistance
    budget = math.tan(max_climbable_slope_rad(terrain_class.friction_mu, crr, MARGIN)) + crr
    return math.sqrt(budget**2 - crr**2)


def test_mud_side_slope_limits_are_the_friction_circles_less_the_margin():
    assert math.degrees(math.atan(driving_limit())) == pytest.approx(11.09, abs=0.01)
    # Without the margin it is the simulator's: sqrt(mu^2 - crr^2) (tests/hil/test_sideways_slide.py).
    assert math.sqrt(MUD.friction_mu**2 - MUD.rolling_resistance**2) == pytest.approx(0.2598, abs=1e-4)


@pytest.mark.parametrize(("grade", "forbidden"), [(0.95, False), (1.05, True)])
def test_crossing_a_mud_side_slope_past_the_limit_is_forbidden(grade, forbidden):
    """Along the contour (east, the ground rising to the north) just below and above the limit; the same
    slope climbed head-on (north) is ruled by the climb rule alone, which forbids both (mud climbs 5.5 deg
    with the margin): the side rule adds nothing there."""
    tan_side = grade * driving_limit()
    factors = direction_factors(plane(0.0, tan_side), PARAMS)
    inside = (slice(2, -2), slice(2, -2))
    assert np.isinf(factors[EAST][inside]).all() == forbidden
    assert np.isfinite(factors[EAST][inside]).all() == (not forbidden)
    # Firm ground holds the same slope (its budget is far larger): the rule is the class's.
    firm = direction_factors(plane(0.0, tan_side, class_id=0), PARAMS)
    assert np.isfinite(firm[EAST][inside]).all()


def test_a_diagonal_climb_uses_friction_the_side_slope_then_lacks():
    """Crossing a side slope that the rover holds when it drives along the contour, while also climbing
    a little (within the climb rule): the pull uphill takes friction from the circle, and it slides."""
    side = 0.8 * driving_limit()
    climb = 0.06  # below mud's climb limit with the margin (tan 5.5 deg = 0.097)
    assert climb < math.tan(max_climbable_slope_rad(MUD.friction_mu, MUD.rolling_resistance, MARGIN))
    contour = direction_factors(plane(0.0, side), PARAMS)
    assert np.isfinite(contour[EAST][5:-5, 5:-5]).all()
    climbing = direction_factors(plane(climb, side), PARAMS)
    assert np.isinf(climbing[EAST][5:-5, 5:-5]).all()
    level_climb = direction_factors(plane(climb, 0.0), PARAMS)
    assert np.isfinite(level_climb[EAST][5:-5, 5:-5]).all()  # no side slope: the climb rule alone


def test_with_no_side_slope_the_rule_adds_nothing_to_the_climb_and_hold_rules():
    """Straight up and down slopes on every class: forbidden exactly where the climb or hold rule says."""
    for class_id, terrain_class in TERRAIN_CLASSES.items():
        tan_climb = math.tan(
            max_climbable_slope_rad(terrain_class.friction_mu, terrain_class.rolling_resistance, MARGIN)
        )
        tan_hold = math.tan(math.atan(terrain_class.friction_mu) - MARGIN)
        for grade in np.linspace(0.0, 1.0, 41).tolist():
            factors = direction_factors(plane(grade, 0.0, class_id), PARAMS)
            east, west = factors[EAST][5:-5, 5:-5], factors[MOVES.tolist().index([0, -1])][5:-5, 5:-5]
            pitch_ok = math.atan(grade) <= PARAMS.tip_pitch_rad - DirectionWeights().tip_margin_rad
            assert np.isinf(east).all() == (grade > tan_climb or not pitch_ok)
            assert np.isinf(west).all() == (grade > tan_hold or not pitch_ok)
