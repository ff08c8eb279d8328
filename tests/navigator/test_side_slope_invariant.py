"""The planner's guarantee that replaced its side-slope rule (``navigator.direction_costs``' module doc):
on every cell the cost grid lets through, whatever the heading, the wheels' friction circles hold the body
sideways, driving on and standing still. It fails if the cell rule (``navigator.costs``) is relaxed past
the friction (with no climb limit at all, 4 of the 6 classes fail)."""

import math

import numpy as np
import pytest

from navigator.astar_kernel import MOVES
from navigator.costs import ground_cost
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TERRAIN_CLASSES
from navigator.vehicle import VehicleParams

PARAMS = VehicleParams()


def plane(grad_x: float, grad_y: float, class_id: int) -> TerrainMap:
    ys, xs = np.mgrid[0:7, 0:7] * 0.25
    return TerrainMap(
        grad_x * xs + grad_y * ys, np.full((7, 7), class_id, np.uint8), np.zeros((7, 7), bool), 0.25
    )


@pytest.mark.parametrize("class_id", sorted(TERRAIN_CLASSES))
def test_every_passable_cell_holds_the_body_sideways_at_every_heading(class_id):
    terrain_class = TERRAIN_CLASSES[class_id]
    mu, crr = terrain_class.friction_mu, terrain_class.rolling_resistance
    passable = 0
    tightest = 0.0  # the largest share of mu^2 a passable move uses
    for grade in np.linspace(0.0, 1.2 * mu, 25).tolist():
        for angle in np.radians(np.arange(0.0, 360.0, 15.0)).tolist():
            grad_x, grad_y = grade * math.cos(angle), grade * math.sin(angle)
            if ground_cost(plane(grad_x, grad_y, class_id), PARAMS).lethal[3, 3]:
                continue
            passable += 1
            for d_row, d_col in MOVES.tolist():
                norm = math.hypot(d_row, d_col)
                along = (grad_x * d_col + grad_y * d_row) / norm
                cross = abs(grad_x * d_row - grad_y * d_col) / norm
                tan_roll = cross / math.sqrt(1.0 + along * along)  # TerrainMap.tilt_at's roll
                along_load = along * math.sqrt(1.0 + tan_roll * tan_roll)  # tan(pitch) / cos(roll)
                driving = tan_roll**2 + max(along_load + crr, 0.0) ** 2
                standing = tan_roll**2 + along_load**2
                assert driving <= mu**2 and standing <= mu**2, (grade, angle, d_row, d_col)
                tightest = max(tightest, driving / mu**2)
    assert passable > 24  # the level and some slopes passed: the check was not vacuous
    assert tightest > 0.6  # and it came near the friction's limit
