"""The rover's body must stand clear at the start: its footprint there may not overlap anything.

``hil.scenario_placement`` refuses a start *point* inside an obstacle when the scenario loads. The body is
bigger than a point: an obstacle whose disc reaches into the footprint rectangle (the rover config's
``[vehicle] footprint_length_m`` x ``footprint_width_m``, turned by ``start.yaw_deg``), a moving obstacle
waiting at its first waypoint on top of the rover, a maze wall or ``obstacles`` layer cell under it, or
a start so near the map's edge that the rectangle leaves the map, is a collision on the simulator's first
tick (``hil.dynamics``, ``hil.world`` use these same tests) before the rover has done anything. That is a
mistake in the scenario, refused naming its file and the key to change. The footprint comes from the
rover config, so the check runs once both are loaded (``rover hil trial``, ``rover hil peer``, each
variant of a campaign).
"""

from __future__ import annotations

import numpy as np

from hil.scenario import Scenario
from logs.settings import ConfigError
from navigator.footprint import Footprint, disc_gap_m, overlapped_cells
from navigator.terrain import disc_mask
from navigator.vehicle import VehicleParams


def check_start_clear(scenario: Scenario, vehicle: VehicleParams) -> None:
    """``ConfigError`` (the scenario file, the key) if the rover's footprint at the start overlaps an
    obstacle, a moving obstacle's starting place, the terrain's obstacle layer or the map's edge."""
    footprint = Footprint.of(vehicle)
    pose = (scenario.start_xy[0], scenario.start_xy[1], scenario.start_yaw_rad)
    body = (
        f"the rover's {footprint.length_m:g} x {footprint.width_m:g} m footprint at the start "
        f"{_xy(scenario.start_xy)} (yaw {np.degrees(scenario.start_yaw_rad):g} deg)"
    )
    for index, moving in enumerate(scenario.moving_obstacles):
        first = moving.waypoints[0]
        gap = disc_gap_m(pose, footprint, first, moving.radius_m)
        if gap < 0.0:
            raise ConfigError(
                scenario.source,
                f"moving_obstacles[{index}].waypoints",
                f"{body} overlaps moving obstacle {moving.id!r} waiting at its first waypoint {_xy(first)} "
                f"(radius {moving.radius_m:g} m) by {-gap:.2f} m: a collision on the first tick; move the "
                "waypoint or the start",
            )
    cells = overlapped_cells(scenario.terrain, pose, footprint)
    if len(cells) == 0:
        return
    rows, cols = scenario.terrain.shape
    on_map = (cells[:, 0] >= 0) & (cells[:, 0] < rows) & (cells[:, 1] >= 0) & (cells[:, 1] < cols)
    hit = cells[on_map]
    for index, obstacle in enumerate(scenario.obstacles):
        mask = disc_mask(scenario.terrain, obstacle.x, obstacle.y, obstacle.radius_m)
        if len(hit) and mask[hit[:, 0], hit[:, 1]].any():
            gap = disc_gap_m(pose, footprint, (obstacle.x, obstacle.y), obstacle.radius_m)
            raise ConfigError(
                scenario.source,
                f"obstacles[{index}].xy",
                f"{body} overlaps obstacle {obstacle.id!r} (centre {_xy((obstacle.x, obstacle.y))}, radius "
                f"{obstacle.radius_m:g} m; {_depth(gap)}): a collision on the first tick; move the obstacle "
                "or the start",
            )
    if len(hit):
        row, col = (int(v) for v in hit[0])
        raise ConfigError(
            scenario.source,
            "start.xy",
            f"{body} overlaps the terrain's obstacle layer (cell row {row}, col {col}): a collision on the "
            "first tick; move the start",
        )
    raise ConfigError(
        scenario.source,
        "start.xy",
        f"{body} reaches past the map's edge: a collision on the first tick; move the start inward",
    )


def _xy(point: tuple[float, float]) -> str:
    return f"({point[0]:g}, {point[1]:g})"


def _depth(gap_m: float) -> str:
    # The map holds the disc as the cells whose centres it covers, which can reach a little past the disc
    # itself: then the body touches a cell of it, not the disc, and a negative overlap would mislead.
    if gap_m < 0.0:
        return f"{-gap_m:.2f} m deep"
    return f"{gap_m:.2f} m from its edge, inside a map cell it covers"
