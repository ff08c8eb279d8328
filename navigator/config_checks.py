"""Rover-config values that are each in range but contradict each other across tables.

Each table checks its own keys when it is read (``from_table``); these checks need two tables at once, so
they run once the whole config is assembled. Each error names both keys and both values. Only pairs that
are wrong whatever the rover are checked: a follower faster than the wheels can drive, a lookahead shorter
than one map cell, a stuck check that can never fire or fires on a rover moving as commanded.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from logs.settings import ConfigError
from navigator.fence_shape import overlaps_box

if TYPE_CHECKING:
    from navigator.config import RoverConfig


def check_cross_fields(config: RoverConfig) -> None:
    """Raise ``ConfigError`` (naming the file and the first key of the pair) for the first contradiction."""
    follower, vehicle, safety = config.follower, config.vehicle, config.safety

    def refuse(key: str, problem: str) -> ConfigError:
        return ConfigError(config.source, key, problem)

    if config.control_loop == "phase-locked" and config.pacing_sensor == "wheels":
        # Wheel status comes as six controllers' frames, each read as it lands: no one sample time a tick
        # can be phase-locked to (the loop would lock on to reads a tenth of a millisecond apart).
        raise refuse(
            "control_loop",
            '"phase-locked" needs a pacing sensor with one sample per period (pacing_sensor = "imu", '
            'or "gps" / "none" for a free-running loop); with pacing_sensor = "wheels" use "sensor-paced"',
        )
    if follower.max_speed_mps > vehicle.max_wheel_speed_mps:
        # Mixing would scale every command down to the wheel limit: the follower's speed and curvature
        # limits would no longer be what the rover drives.
        raise refuse(
            "follower.max_speed_mps",
            f"{follower.max_speed_mps:g} m/s is faster than vehicle.max_wheel_speed_mps "
            f"{vehicle.max_wheel_speed_mps:g} m/s, the fastest the wheels can drive",
        )
    if config.planner.yield_speed_mps > follower.max_speed_mps:
        # Backing off faster than the rover is allowed to drive forward: the follower's own limit is what
        # its stopping distances and the safety checks were set for.
        raise refuse(
            "planner.yield_speed_mps",
            f"{config.planner.yield_speed_mps:g} m/s is faster than follower.max_speed_mps "
            f"{follower.max_speed_mps:g} m/s",
        )
    if config.terrain is not None and follower.lookahead_m < config.terrain.resolution_m:
        # The plan runs from cell centre to cell centre; a target closer than one cell chases each step of
        # that staircase instead of the path's direction.
        raise refuse(
            "follower.lookahead_m",
            f"{follower.lookahead_m:g} m is shorter than one map cell (map.resolution_m "
            f"{config.terrain.resolution_m:g} m)",
        )
    if config.terrain is not None and safety.fence:
        terrain = config.terrain
        rows, cols = terrain.shape
        ox, oy = terrain.origin_xy
        far = (ox + cols * terrain.resolution_m, oy + rows * terrain.resolution_m)
        if not overlaps_box(safety.fence, (ox, oy), far):
            # Every goal on the map would be refused and the rover held wherever it stands: a fence in
            # another frame (relative to the start, say) than the map's local ENU metres.
            raise refuse(
                "safety.fence",
                f"{list(map(list, safety.fence))} lies wholly off the map, which covers "
                f"x [{ox:g}, {far[0]:g}) and y [{oy:g}, {far[1]:g}): both are in the map's local ENU metres",
            )
    if safety.stuck_time_s > 0.0:
        if safety.stuck_max_speed_mps >= safety.stuck_min_command_mps:
            raise refuse(
                "safety.stuck_max_speed_mps",
                f"{safety.stuck_max_speed_mps:g} m/s must be below safety.stuck_min_command_mps "
                f"{safety.stuck_min_command_mps:g} m/s, or a rover driving as commanded counts as stuck",
            )
        if safety.stuck_min_command_mps > follower.max_speed_mps:
            raise refuse(
                "safety.stuck_min_command_mps",
                f"{safety.stuck_min_command_mps:g} m/s is above follower.max_speed_mps "
                f"{follower.max_speed_mps:g} m/s, so the stuck check could never fire "
                "(set safety.stuck_time_s = 0 to turn it off)",
            )
