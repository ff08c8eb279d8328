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
    elif not ground.made_for(terrain):
        raise ParameterError(
            "the ground cost given was made for another terrain's elevation and class layers"
        )
    cost = ground.cost.copy()
    clearance_m = params.footprint_radius_m + inflation_m
    lethal = ground.lethal | inflate_obstacles(terrain, clearance_m, edge_is_obstacle)
    if proximity_weight > 0.0 and proximity_band_m > 0.0 and terrain.obstacles.any():
        distance_m = ndimage.distance_transform_edt(~terrain.obstacles) * terrain.resolution_m
        cost += proximity_weight * np.clip(1.0 - (distance_m - clearance_m) / proximity_band_m, 0.0, 1.0)
    cost[lethal] = LETHAL
    return cost


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
    res = terrain.resolution_m
    reach = math.ceil(clearance_m / res + 0.5)
    offsets = np.arange(-reach, reach + 1)
    gap = np.maximum(np.abs(offsets) - 0.5, 0.0) * res
    structure = (gap[:, np.newaxis] ** 2 + gap[np.newaxis, :] ** 2) < clearance_m**2
    obstacles = terrain.obstacles
    if edge_is_obstacle:
        # A ring of obstacle cells just outside the map stands for "off the map".
        obstacles = np.pad(obstacles, 1, constant_values=True)
    # The obstacle cells themselves are lethal even with zero clearance (an empty structuring element).
    inflated = obstacles | ndimage.binary_dilation(obstacles, structure=structure)
    return np.asarray(inflated[1:-1, 1:-1] if edge_is_obstacle else inflated, dtype=bool)


def _roughness(elevation: np.ndarray) -> np.ndarray:
    """RMS over each 3 x 3 neighbourhood of the elevation minus its 3 x 3 mean (metres).

    Removing the local mean first keeps a smooth, even slope at zero roughness (its mean equals its centre
    value), so slope is not counted twice: only bumps and steps show up.
    """
    residual = elevation - ndimage.uniform_filter(elevation, size=3, mode="nearest")
    # Clamp: the filter can round a zero mean square to a tiny negative number.
    return np.sqrt(np.maximum(ndimage.uniform_filter(residual * residual, size=3, mode="nearest"), 0.0))
