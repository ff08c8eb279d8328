"""Traversability: one cost per map cell for the planner, from terrain class, slope, roughness, obstacles.

Uses the vehicle physics of ``navigator.vehicle`` with the parameters the planner *believes*.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from navigator.errors import ParameterError
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TERRAIN_CLASSES, TerrainClass
from navigator.vehicle import VehicleParams, max_climbable_slope_rad

LETHAL = math.inf


@dataclass(frozen=True)
class CostModel:
    """Weights of the cost formula (see ``traversability_cost``).

    ``slope_weight`` multiplies tan(slope) (dimensionless); ``roughness_weight`` multiplies the local
    standard deviation of elevation (1/m); ``climb_margin_rad`` and ``tip_margin_rad`` keep the planner away
    from the physical limits; ``inflation_m`` adds clearance beyond the footprint circle;
    ``proximity_weight`` and ``proximity_band_m`` add a soft cost that falls off linearly over a band
    beyond the lethal clearance, so paths keep room for tracking and estimation error.
    """

    inflation_m: float = 0.1
    proximity_weight: float = 4.0
    proximity_band_m: float = 1.0
    slope_weight: float = 2.0
    roughness_weight: float = 10.0
    climb_margin_rad: float = math.radians(3.0)
    tip_margin_rad: float = math.radians(10.0)
    edge_is_obstacle: bool = True

    def __post_init__(self) -> None:
        for name in (
            "inflation_m",
            "proximity_weight",
            "proximity_band_m",
            "slope_weight",
            "roughness_weight",
            "climb_margin_rad",
            "tip_margin_rad",
        ):
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0.0:
                raise ParameterError(f"cost model {name} must be a finite number >= 0, got {value}")

    def grid(
        self,
        terrain: TerrainMap,
        params: VehicleParams,
        classes: dict[int, TerrainClass] = TERRAIN_CLASSES,
        *,
        ground: GroundCost | None = None,
    ) -> np.ndarray:
        """The cost grid; ``ground`` (optional): this model's ``ground_cost`` of the same terrain layers,
        kept by a caller that recomputes the grid as obstacles are added (``Planner``)."""
        return traversability_cost(
            terrain,
            params,
            classes,
            inflation_m=self.inflation_m,
            proximity_weight=self.proximity_weight,
            proximity_band_m=self.proximity_band_m,
            slope_weight=self.slope_weight,
            roughness_weight=self.roughness_weight,
            climb_margin_rad=self.climb_margin_rad,
            tip_margin_rad=self.tip_margin_rad,
            edge_is_obstacle=self.edge_is_obstacle,
            ground=ground,
        )

    def update_grid(
        self,
        cost: np.ndarray,
        terrain: TerrainMap,
        params: VehicleParams,
        ground: GroundCost,
        before: np.ndarray,
    ) -> GridChange:
        """Bring ``cost``, this model's grid of ``terrain``'s layers with the obstacle layer ``before``, up to
        ``terrain``'s obstacles, in place; returns where the cost changed and the windows recomputed.

        Only the windows an added or removed obstacle cell can reach are recomputed (``_ObstacleTerms``),
        so the result is ``grid(terrain, params, ground=ground)`` bit for bit at the cost of those windows.
        """
        _check_ground(ground, terrain)
        if cost.shape != terrain.shape or before.shape != terrain.shape:
            raise ParameterError(
                f"cost grid {cost.shape} and obstacle layer {before.shape} must have the map's shape "
                f"{terrain.shape}"
            )
        terms = self._terms(params)
        changed = np.zeros(terrain.shape, dtype=bool)
        windows = change_windows(before != terrain.obstacles, terms.reach_cells(terrain.resolution_m))
        for window in windows:
            rows, cols = window_slices(window)
            fresh = terms.cost(ground, terrain.obstacles, terrain.resolution_m, window)
            changed[rows, cols] |= cost[rows, cols] != fresh  # windows may overlap: |=, not =
            cost[rows, cols] = fresh
        return GridChange(changed, tuple(windows))

    def _terms(self, params: VehicleParams) -> _ObstacleTerms:
        return _ObstacleTerms(
            params.footprint_radius_m + self.inflation_m,
            self.proximity_weight,
            self.proximity_band_m,
            self.edge_is_obstacle,
        )

    def ground_cost(
        self, terrain: TerrainMap, params: VehicleParams, classes: dict[int, TerrainClass] = TERRAIN_CLASSES
    ) -> GroundCost:
        """The part of ``grid`` that obstacles do not change, for ``grid(..., ground=...)``."""
        return ground_cost(
            terrain,
            params,
            classes,
            slope_weight=self.slope_weight,
            roughness_weight=self.roughness_weight,
            climb_margin_rad=self.climb_margin_rad,
            tip_margin_rad=self.tip_margin_rad,
        )


@dataclass(frozen=True, eq=False)
class GroundCost:
    """The obstacle-free part of ``traversability_cost`` for one terrain's elevation and class layers:
    the class, slope and roughness cost and the slope-lethal cells (both read-only).

    Adding obstacles to a map (``TerrainMap.with_obstacles``) keeps those layers, so a planner recomputing
    its grid for each obstacle seen reuses this instead of refiltering the whole map (about half of a
    grid's time). It remembers the layers it was made from: ``traversability_cost`` refuses it for others.
    """

    elevation_m: np.ndarray
    terrain_class: np.ndarray
    cost: np.ndarray
    lethal: np.ndarray

    def made_for(self, terrain: TerrainMap) -> bool:
        return terrain.elevation_m is self.elevation_m and terrain.terrain_class is self.terrain_class


def traversability_cost(
    terrain: TerrainMap,
    params: VehicleParams,
    classes: dict[int, TerrainClass] = TERRAIN_CLASSES,
    *,
    inflation_m: float = 0.1,
    proximity_weight: float = 4.0,
    proximity_band_m: float = 1.0,
    slope_weight: float = 2.0,
    roughness_weight: float = 10.0,
    climb_margin_rad: float = math.radians(3.0),
    tip_margin_rad: float = math.radians(10.0),
    edge_is_obstacle: bool = True,
    ground: GroundCost | None = None,
) -> np.ndarray:
    """Cost per cell, ``(rows, cols)`` float64: ``>= 1`` where traversable, ``np.inf`` where lethal.

    For a cell of class ``c`` with slope angle ``s`` (steepest descent, ``tan s = |grad z|``) and
    roughness ``r`` (metres: RMS over the cell and its 8 neighbours of the elevation minus its 3 x 3 local
    mean, so an even slope is not rough)::

        cost = cost_factor[c] * (1 + slope_weight * tan(s) + roughness_weight * r)
               + proximity_weight * max(0, 1 - (d - clearance) / proximity_band_m)

    where ``d`` is the distance from the cell centre to the nearest obstacle cell centre and
    ``clearance = footprint_radius + inflation_m`` (the soft band is zero when ``proximity_band_m`` is 0).

    A cell is lethal (``inf``) when any of these holds:

    * its centre is within ``footprint_radius + inflation_m`` of any part of an obstacle cell (or of the
      map edge when ``edge_is_obstacle``: the rover must stay on the map);
    * ``s > max_climbable_slope(mu[c], crr[c]) - climb_margin_rad`` (it could not drive up it);
    * ``s > min(tip_roll, tip_pitch) - tip_margin_rad``: some heading across the cell tilts the rover past a
      tip angle (the steepest roll or pitch over all headings equals ``s``).

    The slope tests do not depend on heading yet; a direction-dependent cost would replace the scalar
    slope by the slope along each of the 8 moves (the design keeps the grid per cell for now).

    ``ground`` (optional): ``ground_cost`` of this terrain's layers made before with the same weights and
    classes (the first two terms and the slope tests), reused; ParameterError for another terrain's.
    """
    if ground is None:
        ground = ground_cost(
            terrain,
            params,
            classes,
            slope_weight=slope_weight,
            roughness_weight=roughness_weight,
            climb_margin_rad=climb_margin_rad,
            tip_margin_rad=tip_margin_rad,
        )
    else:
        _check_ground(ground, terrain)
    terms = _ObstacleTerms(
        params.footprint_radius_m + inflation_m, proximity_weight, proximity_band_m, edge_is_obstacle
    )
    rows, cols = terrain.shape
    return terms.cost(ground, terrain.obstacles, terrain.resolution_m, (0, rows, 0, cols))


def _check_ground(ground: GroundCost, terrain: TerrainMap) -> None:
    if not ground.made_for(terrain):
        raise ParameterError(
            "the ground cost given was made for another terrain's elevation and class layers"
        )


def ground_cost(
    terrain: TerrainMap,
    params: VehicleParams,
    classes: dict[int, TerrainClass] = TERRAIN_CLASSES,
    *,
    slope_weight: float = 2.0,
    roughness_weight: float = 10.0,
    climb_margin_rad: float = math.radians(3.0),
    tip_margin_rad: float = math.radians(10.0),
) -> GroundCost:
    """The obstacle-free part of ``traversability_cost`` (see there): the class, slope and roughness cost,
    and the cells too steep to climb or to cross without tipping."""
    grad_x, grad_y = terrain.slope_gradient()
    tan_slope = np.hypot(grad_x, grad_y)
    slope = np.arctan(tan_slope)

    class_ids = terrain.terrain_class.astype(np.intp)
    size = max(int(class_ids.max()) + 1, max(classes) + 1)
    cost_factor = np.full(size, np.nan)
    climb_limit = np.full(size, np.nan)
    for class_id, terrain_class in classes.items():
        cost_factor[class_id] = terrain_class.cost_factor
        climb_limit[class_id] = max_climbable_slope_rad(
            terrain_class.friction_mu, terrain_class.rolling_resistance, climb_margin_rad
        )
    if np.any(np.isnan(cost_factor[class_ids])):
        missing = sorted(set(np.unique(class_ids)) - set(classes))
        raise ParameterError(f"terrain classes {missing} on the map have no entry in the class table")

    roughness = _roughness(terrain.elevation_m)
    cost = cost_factor[class_ids] * (1.0 + slope_weight * tan_slope + roughness_weight * roughness)

    tip_limit = min(params.tip_roll_rad, params.tip_pitch_rad) - tip_margin_rad
    lethal = (slope > climb_limit[class_ids]) | (slope > tip_limit)
    cost.setflags(write=False)
    lethal.setflags(write=False)
    return GroundCost(terrain.elevation_m, terrain.terrain_class, cost, lethal)


def inflate_obstacles(terrain: TerrainMap, clearance_m: float, edge_is_obstacle: bool = True) -> np.ndarray:
    """Cells whose centre is closer than ``clearance_m`` to any point of an obstacle cell (or the map edge).

    Exact for square cells: the structuring element holds every cell offset whose nearest point lies within
    the clearance of a cell centre.
    """
    rows, cols = terrain.shape
    return _inflated(
        terrain.obstacles, terrain.resolution_m, clearance_m, edge_is_obstacle, (0, rows, 0, cols)
    )


# (first row, end row, first column, end column) of a block of map cells, ends excluded.
Window = tuple[int, int, int, int]


@dataclass(frozen=True, eq=False)
class GridChange:
    """What ``CostModel.update_grid`` did to a cost grid."""

    changed: np.ndarray  # bool, map shape: the cells whose cost differs from before
    # The windows recomputed: no cell outside them changed, so a caller keeping a copy of the grid
    # (``RepairingPlanner.update_costs``) need look at these alone.
    windows: tuple[Window, ...]


def window_slices(window: Window) -> tuple[slice, slice]:
    return slice(window[0], window[1]), slice(window[2], window[3])


def _inflation_structure(resolution_m: float, clearance_m: float) -> tuple[np.ndarray, int]:
    """The dilation's structuring element and its reach (cells from its centre to its edge)."""
    reach = math.ceil(clearance_m / resolution_m + 0.5)
    offsets = np.arange(-reach, reach + 1)
    gap = np.maximum(np.abs(offsets) - 0.5, 0.0) * resolution_m
    return (gap[:, np.newaxis] ** 2 + gap[np.newaxis, :] ** 2) < clearance_m**2, reach


def _obstacle_block(
    obstacles: np.ndarray, window: Window, margin: int, edge_is_obstacle: bool
) -> tuple[np.ndarray, int, int]:
    """``obstacles`` over ``window`` grown by ``margin`` cells, cut to the map, and its first row and column.

    With ``edge_is_obstacle`` the ring of cells just outside the map belongs to the map and is an obstacle
    ("off the map"); beyond the cut the dilation and the distance transform see nothing, as for the map.
    """
    rows, cols = obstacles.shape
    ring = 1 if edge_is_obstacle else 0
    row0, row1 = max(window[0] - margin, -ring), min(window[1] + margin, rows + ring)
    col0, col1 = max(window[2] - margin, -ring), min(window[3] + margin, cols + ring)
    block = np.full((row1 - row0, col1 - col0), edge_is_obstacle)  # what lies outside the map: the ring
    in_row0, in_row1, in_col0, in_col1 = max(row0, 0), min(row1, rows), max(col0, 0), min(col1, cols)
    block[in_row0 - row0 : in_row1 - row0, in_col0 - col0 : in_col1 - col0] = obstacles[
        in_row0:in_row1, in_col0:in_col1
    ]
    return block, row0, col0


def _inflated(
    obstacles: np.ndarray, resolution_m: float, clearance_m: float, edge_is_obstacle: bool, window: Window
) -> np.ndarray:
    """``inflate_obstacles`` over ``window``: a cell there is lethal through obstacle cells within the
    structuring element's reach, so the dilation runs on the window grown by that reach, and no further."""
    structure, reach = _inflation_structure(resolution_m, clearance_m)
    block, row0, col0 = _obstacle_block(obstacles, window, reach, edge_is_obstacle)
    # The obstacle cells themselves are lethal even with zero clearance (an empty structuring element).
    inflated = block | ndimage.binary_dilation(block, structure=structure)
    return np.asarray(inflated[window[0] - row0 : window[1] - row0, window[2] - col0 : window[3] - col0])


@dataclass(frozen=True)
class _ObstacleTerms:
    """The obstacle-dependent part of ``traversability_cost`` (inflation and the clearance band), over any
    window of the map, so that an obstacle update recomputes only the windows it can reach.

    Reach: a cell's inflation reads obstacle cells within the structuring element's reach; its clearance
    term is zero past ``clearance_m + band_m`` from every obstacle (the term is clipped there). The exact
    distance transform itself reaches without bound, but a cell whose nearest obstacle lies further than
    ``proximity_reach`` cells gets a zero term either way: the transform of the window grown by that reach
    gives every cell of the window either its true distance or a distance past the band (a term of zero,
    as its true distance gives). One cell of margin on the band keeps rounding at its end out of it.
    """

    clearance_m: float
    weight: float
    band_m: float
    edge_is_obstacle: bool

    @property
    def has_band(self) -> bool:
        return self.weight > 0.0 and self.band_m > 0.0

    def proximity_reach(self, resolution_m: float) -> int:
        return math.ceil((self.clearance_m + self.band_m) / resolution_m) + 1 if self.has_band else 0

    def reach_cells(self, resolution_m: float) -> int:
        """How far (cells, along a row or a column) a change of one obstacle cell can change costs."""
        return max(
            _inflation_structure(resolution_m, self.clearance_m)[1], self.proximity_reach(resolution_m)
        )

    def cost(
        self, ground: GroundCost, obstacles: np.ndarray, resolution_m: float, window: Window
    ) -> np.ndarray:
        """The cost grid over ``window`` for the obstacle layer ``obstacles`` (a new array)."""
        rows, cols = window_slices(window)
        cost = ground.cost[rows, cols].copy()
        if self.has_band:
            block, row0, col0 = _obstacle_block(obstacles, window, self.proximity_reach(resolution_m), False)
            if block.any():  # no obstacle within reach: no term (nor on a map without obstacles)
                distance = ndimage.distance_transform_edt(~block)
                distance_m = distance[
                    window[0] - row0 : window[1] - row0, window[2] - col0 : window[3] - col0
                ]
                cost += self.weight * np.clip(
                    1.0 - (distance_m * resolution_m - self.clearance_m) / self.band_m, 0.0, 1.0
                )
        lethal = ground.lethal[rows, cols] | _inflated(
            obstacles, resolution_m, self.clearance_m, self.edge_is_obstacle, window
        )
        cost[lethal] = LETHAL
        return cost


def change_windows(changed: np.ndarray, reach: int) -> list[Window]:
    """Windows (cut to the map) holding every cell within ``reach`` cells of a ``changed`` cell.

    Changed cells are grouped by tiles of ``2 reach + 1`` cells: changes in touching tiles share one window
    (the bounding box of the group grown by ``reach``), so nearby changes are not recomputed twice, and
    changes far apart (an obstacle taken off here, another added there) do not span the map between them.
    """
    # The rows with a change first: a whole-map nonzero costs ~6 ms a million cells, ``any`` a tenth of it.
    active_rows = np.flatnonzero(changed.any(axis=1))
    if active_rows.size == 0:
        return []
    in_active, changed_cols = np.nonzero(changed[active_rows])
    changed_rows = active_rows[in_active]
    rows, cols = changed.shape
    tile = 2 * reach + 1
    tile_rows, tile_cols = changed_rows // tile, changed_cols // tile
    dirty = np.zeros((rows // tile + 1, cols // tile + 1), dtype=bool)
    dirty[tile_rows, tile_cols] = True
    labels, groups = ndimage.label(dirty, structure=np.ones((3, 3), dtype=bool))
    group = labels[tile_rows, tile_cols] - 1
    first_row, first_col = np.full(groups, rows), np.full(groups, cols)
    last_row, last_col = np.full(groups, -1), np.full(groups, -1)
    np.minimum.at(first_row, group, changed_rows)
    np.minimum.at(first_col, group, changed_cols)
    np.maximum.at(last_row, group, changed_rows)
    np.maximum.at(last_col, group, changed_cols)
    return [
        (
            max(int(r0) - reach, 0),
            min(int(r1) + 1 + reach, rows),
            max(int(c0) - reach, 0),
            min(int(c1) + 1 + reach, cols),
        )
        for r0, r1, c0, c1 in zip(first_row, last_row, first_col, last_col, strict=True)
    ]


def _roughness(elevation: np.ndarray) -> np.ndarray:
    """RMS over each 3 x 3 neighbourhood of the elevation minus its 3 x 3 mean (metres).

    Removing the local mean first keeps a smooth, even slope at zero roughness (its mean equals its centre
    value), so slope is not counted twice: only bumps and steps show up.
    """
    residual = elevation - ndimage.uniform_filter(elevation, size=3, mode="nearest")
    # Clamp: the filter can round a zero mean square to a tiny negative number.
    return np.sqrt(np.maximum(ndimage.uniform_filter(residual * residual, size=3, mode="nearest"), 0.0))
