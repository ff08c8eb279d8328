"""Where a scenario puts the rover and its goals must be free ground: not inside any obstacle.

A start inside an obstacle is a collision on the first tick and then "start cell is lethal"; a goal
inside one has no path and the trial runs until it gives up. Both are mistakes in the file, so they are
refused at load, naming the obstacle and how far the point is from it.

"Inside" means what the maps will hold: a point within an obstacle's radius, or in a grid cell the
obstacle's disc covers (``navigator.terrain.disc_mask``: cells whose centre lies within the radius, and
the cell of the centre itself), or in a cell of the terrain's own obstacle layer (maze walls, an
``obstacles`` layer). Unknown obstacles (``known = false``) count too: the rover meets them all the same.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

from logs.settings import Table
from navigator.terrain import TerrainMap


class Disc(Protocol):
    """A round obstacle (``hil.scenario.Obstacle``): its id, centre and radius in metres."""

    @property
    def id(self) -> str: ...
    @property
    def x(self) -> float: ...
    @property
    def y(self) -> float: ...
    @property
    def radius_m(self) -> float: ...


def check_clear_of_obstacles(
    terrain: TerrainMap, obstacles: Sequence[Disc], xy: tuple[float, float], table: Table, key: str
) -> None:
    """``ConfigError`` on ``table``'s ``key`` if ``xy`` (on the map) lies inside an obstacle."""
    x, y = xy
    cell = terrain.cell_of(x, y)
    for obstacle in obstacles:
        distance = math.hypot(x - obstacle.x, y - obstacle.y)
        if distance <= obstacle.radius_m or _covers(terrain, obstacle, cell):
            within = distance <= obstacle.radius_m
            how = "" if within else f", in a {terrain.resolution_m:g} m map cell it covers"
            raise table.error(
                key,
                f"({x:g}, {y:g}) is inside obstacle {obstacle.id!r} "
                f"(centre ({obstacle.x:g}, {obstacle.y:g}), radius {obstacle.radius_m:g} m): "
                f"{distance:.2f} m from its centre{how}",
            )
    if terrain.obstacles[cell]:
        row, col = cell
        raise table.error(
            key, f"({x:g}, {y:g}) is on the terrain's obstacle layer (cell row {row}, col {col})"
        )


def _covers(terrain: TerrainMap, obstacle: Disc, cell: tuple[int, int]) -> bool:
    """Whether ``disc_mask`` of the obstacle marks ``cell`` (the same rule, for one cell)."""
    cx, cy = terrain.center_of(*cell)
    if math.hypot(cx - obstacle.x, cy - obstacle.y) <= obstacle.radius_m:
        return True
    return terrain.contains(obstacle.x, obstacle.y) and terrain.cell_of(obstacle.x, obstacle.y) == cell
