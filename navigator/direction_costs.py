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
* ``-along > tan(atan(mu) - climb_margin)`` (cannot hold itself: it would slide down with braked wheels).

No rule of its own forbids crossing a side slope the wheels cannot hold on sideways: within a class
none could fire between cells the cost grid lets through. Per unit of normal load the body needs
``tan(roll)`` sideways and ``along_load = tan(pitch) / cos(roll)`` along its heading, and
``tan(roll)^2 + along_load^2 = along^2 + cross^2 = |grad z|^2`` whatever the heading; the cost grid
(``navigator.costs``) makes a cell lethal past ``|grad z| = tan(climb limit)`` of its class, and
``tan(climb limit) + crr <= mu``, so on every passable cell each wheel's friction circle holds the body
driving on (``tan(roll)^2 + (along_load + crr)^2 <= mu^2``) and standing still
(``tan(roll)^2 + along_load^2 <= mu^2``). ``tests/navigator/test_side_slope_invariant.py`` keeps that
guarantee: it fails if the cell rule is relaxed past the friction. (Where two classes meet, a move's
slope, the mean of its cells', can pass the firmer cell's limit and exceed the softer class's for that one
step; a rover on the softer cell's own slope is within it.)

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
    for class_id, terrain_class in classes.items():
        tan_climb[class_id] = math.tan(
            max_climbable_slope_rad(
                terrain_class.friction_mu, terrain_class.rolling_resistance, w.climb_margin_rad
            )
        )
        tan_hold[class_id] = math.tan(max(0.0, math.atan(terrain_class.friction_mu) - w.climb_margin_rad))
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
        )
        factor[forbidden] = np.inf
        factors[move] = factor
    return factors
