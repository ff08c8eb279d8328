"""Direction-dependent move costs: climbing, descending and crossing a slope sideways cost differently.

For the move ``m`` (order of ``navigator.astar_kernel.MOVES``) out of cell ``a`` into its neighbour ``b``
the slope is the mean of the two cells' elevation gradients ``grad``; with ``d`` the unit direction of
the move in ENU (east = +col, north = +row)::

    along = grad . d          (> 0: uphill)         cross = |grad x d|   (side slope)
    pitch = atan(along)       roll = atan(cross / sqrt(1 + along^2))   (see TerrainMap.tilt_at)

    factor[m, a] = 1 + climb_weight * max(along, 0) + descent_weight * max(-along, 0)
                     + side_weight * cross

and ``inf`` (the move is forbidden) when the rover driving that way would be beyond a limit:

* ``roll  > tip_roll  - tip_margin``   (tips over sideways: crossing too steep a side slope);
* ``|pitch| > tip_pitch - tip_margin`` (tips over end to end);
* ``along > tan(max_climbable_slope(mu, crr) - climb_margin)`` of either cell's class (cannot climb);
* ``-along > tan(atan(mu) - climb_margin)`` (cannot hold itself: it would slide down with braked wheels);
* on a side slope (``cross > 0``), when the friction the wheels have left sideways cannot hold the body
  (it would slide sideways downhill, off its path: ``hil.traction.sideways_grip``). Per unit of normal
  load the body needs ``tan(roll)`` sideways, and along its heading ``pull = tan(pitch) / cos(roll) + crr``
  to drive on (gravity's part along it, and rolling resistance) or ``brake = -tan(pitch) / cos(roll)`` to
  stand still; each wheel's friction is a circle, so the move is forbidden when
  ``tan(roll)^2 + max(pull, 0)^2 > (tan(max_climbable_slope(mu, crr) - climb_margin) + crr)^2`` (it cannot
  drive across) or ``tan(roll)^2 + max(brake, 0)^2 > tan(atan(mu) - climb_margin)^2`` (it cannot stop
  there), for either cell's class. The budgets are the ones the climb and hold rules above allow along the
  slope, so with no side slope these are those rules exactly; across a level-contour slope they are the
  simulator's holding limits less the margin (mud: 11.1 deg driving, 13.7 deg parked). The cost grid
  (``navigator.costs``) already makes a cell lethal past the climb limit whatever the heading, and
  ``tan(climb limit) = mu - crr < sqrt(mu^2 - crr^2)``, so between cells the cost grid lets through this rule
  forbids nothing on the shipped maps; it states the belief where the sliding is decided, and holds if the
  cell rule's margin or limit is ever relaxed.

Every factor is >= 1, so ``step * mean(cell costs)`` stays a lower bound of every move and the A*
heuristics stay admissible. ``side_weight`` > ``climb_weight`` by default: a rover on a hill prefers to
take it diagonally or head-on over traversing it sideways, where roll eats the tip-over margin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navigator.astar_kernel import MOVES
from navigator.errors import ParameterError
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TERRAIN_CLASSES, TerrainClass
from navigator.vehicle import VehicleParams, max_climbable_slope_rad


@dataclass(frozen=True)
class DirectionWeights:
    """Weights of the direction factor (per unit of tan(slope)) and the margins from physical limits."""

    climb_weight: float = 2.0
    descent_weight: float = 0.5
    side_weight: float = 4.0
    climb_margin_rad: float = math.radians(3.0)
    tip_margin_rad: float = math.radians(10.0)

    def __post_init__(self) -> None:
        for name in ("climb_weight", "descent_weight", "side_weight", "climb_margin_rad", "tip_margin_rad"):
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0.0:
                raise ParameterError(f"direction weight {name} must be a finite number >= 0, got {value}")


def _shifted(layer: np.ndarray, d_row: int, d_col: int) -> np.ndarray:
    """``layer`` at (row + d_row, col + d_col), edge values repeated past the border."""
    padded = np.pad(layer, 1, mode="edge")
    rows, cols = layer.shape
    return padded[1 + d_row : 1 + d_row + rows, 1 + d_col : 1 + d_col + cols]


def _slides_sideways(
    along: np.ndarray,
    cross: np.ndarray,
    class_ids: np.ndarray,
    d_row: int,
    d_col: int,
    crr: np.ndarray,
    pull_budget: np.ndarray,
    hold_budget: np.ndarray,
) -> np.ndarray:
    """Where a move across a side slope leaves the wheels too little friction sideways, in either cell's
    class (the module doc's side-slope rule). ``along``, ``cross``: the move's gradients, (rows, cols)."""
    tan_roll = cross / np.sqrt(1.0 + along * along)  # TerrainMap.tilt_at's roll
    # Gravity along the heading per unit of normal load: tan(pitch) / cos(roll).
    along_load = along * np.sqrt(1.0 + tan_roll * tan_roll)
    sideways = tan_roll * tan_roll
    braking = np.maximum(-along_load, 0.0) ** 2
    slides = np.zeros(along.shape, dtype=bool)
    for ids in (class_ids, _shifted(class_ids, d_row, d_col)):
        pulling = np.maximum(along_load + crr[ids], 0.0) ** 2
        slides |= (sideways + pulling > pull_budget[ids] ** 2) | (sideways + braking > hold_budget[ids] ** 2)
    return slides & (cross > 0.0)


def direction_factors(
    terrain: TerrainMap,
    params: VehicleParams,
    classes: dict[int, TerrainClass] = TERRAIN_CLASSES,
    weights: DirectionWeights | None = None,
) -> np.ndarray:
    """``(8, rows, cols)`` float64 factors >= 1, ``inf`` for moves beyond a limit (see the module doc)."""
    w = weights or DirectionWeights()
    grad_x, grad_y = terrain.slope_gradient()
    class_ids = terrain.terrain_class.astype(np.intp)
    size = max(int(class_ids.max()) + 1, max(classes) + 1)
    tan_climb = np.full(size, np.inf)
    tan_hold = np.full(size, np.inf)
    crr = np.zeros(size)
    for class_id, terrain_class in classes.items():
        tan_climb[class_id] = math.tan(
            max_climbable_slope_rad(
                terrain_class.friction_mu, terrain_class.rolling_resistance, w.climb_margin_rad
            )
        )
        tan_hold[class_id] = math.tan(max(0.0, math.atan(terrain_class.friction_mu) - w.climb_margin_rad))
        crr[class_id] = terrain_class.rolling_resistance
    # The friction budgets (per unit of normal load) of the side-slope rule: driving on, standing still.
    pull_budget = tan_climb + crr
    hold_budget = tan_hold
    roll_limit = params.tip_roll_rad - w.tip_margin_rad
    pitch_limit = params.tip_pitch_rad - w.tip_margin_rad

    factors = np.empty((8, *terrain.shape))
    for move, (d_row, d_col) in enumerate(MOVES.tolist()):
        norm = math.hypot(d_row, d_col)
        dir_x, dir_y = d_col / norm, d_row / norm
        gx = 0.5 * (grad_x + _shifted(grad_x, d_row, d_col))
        gy = 0.5 * (grad_y + _shifted(grad_y, d_row, d_col))
        along = gx * dir_x + gy * dir_y
        cross = np.abs(gx * dir_y - gy * dir_x)
        factor = (
            1.0
            + w.climb_weight * np.maximum(along, 0.0)
            + w.descent_weight * np.maximum(-along, 0.0)
            + w.side_weight * cross
        )
        roll = np.arctan(cross / np.sqrt(1.0 + along * along))
        climb_ok = np.minimum(tan_climb[class_ids], _shifted(tan_climb[class_ids], d_row, d_col))
        hold_ok = np.minimum(tan_hold[class_ids], _shifted(tan_hold[class_ids], d_row, d_col))
        forbidden = (
            (roll > roll_limit)
            | (np.arctan(np.abs(along)) > pitch_limit)
            | (along > climb_ok)
            | (-along > hold_ok)
            | _slides_sideways(along, cross, class_ids, d_row, d_col, crr, pull_budget, hold_budget)
        )
        factor[forbidden] = np.inf
        factors[move] = factor
    return factors
