"""Scenario files: the world a trial runs in (terrain, start, goals, obstacles, sensors, duration).

A scenario is TOML, validated completely before anything starts, with errors that name the file and the
key. The terrain comes from the paper's maze matrix, from .npy layers, or is procedural from a seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from logs.settings import Table, load_toml
from navigator.map_config import terrain_from_table
from navigator.terrain import TerrainMap, disc_mask


@dataclass(frozen=True)
class Obstacle:
    id: str
    x: float
    y: float
    radius_m: float


@dataclass(frozen=True)
class Goal:
    x: float
    y: float
    tolerance_m: float


@dataclass(frozen=True)
class SensorSettings:
    gps_rate_hz: float = 5.0
    gps_noise_m: float = 0.5
    imu_rate_hz: float = 50.0
    gyro_noise_rps: float = 0.005
    accel_noise_mps2: float = 0.05

    @classmethod
    def from_table(cls, table: Table) -> SensorSettings:
        settings = cls(
            gps_rate_hz=table.number("gps_rate_hz", cls.gps_rate_hz, lo=0.1, hi=50.0),
            gps_noise_m=table.number("gps_noise_m", cls.gps_noise_m, lo=0.0, hi=50.0),
            imu_rate_hz=table.number("imu_rate_hz", cls.imu_rate_hz, lo=1.0, hi=1000.0),
            gyro_noise_rps=table.number("gyro_noise_rps", cls.gyro_noise_rps, lo=0.0, hi=1.0),
            accel_noise_mps2=table.number("accel_noise_mps2", cls.accel_noise_mps2, lo=0.0, hi=10.0),
        )
        table.finish()
        return settings


@dataclass(frozen=True)
class Scenario:
    name: str
    source: str
    text: str  # the file as written, attached to every recording
    terrain: TerrainMap  # the true world, static obstacles included
    start_xy: tuple[float, float]
    start_yaw_rad: float
    goals: tuple[Goal, ...]
    obstacles: tuple[Obstacle, ...]
    sensors: SensorSettings
    duration_s: float
    seed: int
    path_tolerance_m: float
    datum: tuple[float, float, float]  # lat, lon, alt of the ENU origin
    terrain_summary: str = ""
    tags: tuple[str, ...] = field(default_factory=tuple)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file; raises ``ConfigError`` naming the file and the key."""
    root = load_toml(path)
    text = Path(path).read_text(encoding="utf-8")
    return scenario_from_table(root, text, base_dir=Path(path).parent)


def scenario_from_table(root: Table, text: str, base_dir: Path) -> Scenario:
    name = root.text("name")
    root.text("description", "")
    duration_s = root.number("duration_s", 120.0, lo=1.0, hi=24 * 3600.0)
    seed = root.integer("seed", 0, lo=0)
    path_tolerance_m = root.number("path_tolerance_m", 0.5, lo=0.01, hi=100.0)
    datum_values = root.numbers("datum", [47.397742, 8.545594, 488.0], length=3)
    if not (-90.0 <= datum_values[0] <= 90.0 and -180.0 <= datum_values[1] <= 180.0):
        raise root.error(
            "datum", f"latitude must be in [-90, 90] and longitude in [-180, 180], got {datum_values}"
        )
    tags = tuple(str(t) for t in root.raw("tags", []))

    terrain, summary = terrain_from_table(root.table("terrain"), base_dir)

    start_table = root.table("start")
    start_xy = start_table.point("xy")
    start_yaw = math.radians(start_table.number("yaw_deg", 0.0, lo=-360.0, hi=360.0))
    start_table.finish()
    _check_inside(terrain, start_xy, start_table, "xy")

    goals = []
    for goal_table in root.tables("goals", optional=False):
        xy = goal_table.point("xy")
        _check_inside(terrain, xy, goal_table, "xy")
        goals.append(Goal(xy[0], xy[1], goal_table.number("tolerance_m", 0.5, lo=0.05, hi=50.0)))
        goal_table.finish()
    if not goals:
        raise root.error("goals", "at least one [[goals]] entry is needed")

    obstacles = []
    seen_ids: set[str] = set()
    for index, obstacle_table in enumerate(root.tables("obstacles")):
        obstacle_id = obstacle_table.text("id", f"obstacle{index}")
        if obstacle_id in seen_ids:
            raise obstacle_table.error("id", f"duplicate obstacle id {obstacle_id!r}")
        seen_ids.add(obstacle_id)
        xy = obstacle_table.point("xy")
        _check_inside(terrain, xy, obstacle_table, "xy")
        radius = obstacle_table.number("radius_m", lo=0.05, hi=50.0)
        obstacle_table.finish()
        obstacles.append(Obstacle(obstacle_id, xy[0], xy[1], radius))
    if obstacles:
        mask = np.zeros(terrain.shape, dtype=bool)
        for obstacle in obstacles:
            mask |= disc_mask(terrain, obstacle.x, obstacle.y, obstacle.radius_m)
        terrain = terrain.with_obstacles(mask)

    sensors = SensorSettings.from_table(root.table("sensors", optional=True))
    root.finish()
    return Scenario(
        name=name,
        source=root.source,
        text=text,
        terrain=terrain,
        start_xy=start_xy,
        start_yaw_rad=start_yaw,
        goals=tuple(goals),
        obstacles=tuple(obstacles),
        sensors=sensors,
        duration_s=duration_s,
        seed=seed,
        path_tolerance_m=path_tolerance_m,
        datum=(datum_values[0], datum_values[1], datum_values[2]),
        terrain_summary=summary,
        tags=tags,
    )


def _check_inside(terrain: TerrainMap, xy: tuple[float, float], table: Table, key: str) -> None:
    if not terrain.contains(*xy):
        raise table.error(key, f"point {xy} lies outside the terrain map")
