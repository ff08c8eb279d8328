"""Scenario files: the world a trial runs in.

Terrain (and the figures of its classes, where they are not the built-in table's), start, goals, static and
moving obstacles, sensor settings, perception, faults over time, duration, seed and success criteria. A
scenario is TOML, validated completely before anything starts, with errors that name the file and the key.
The terrain comes from the paper's maze matrix, from .npy layers, or is procedural from a seed. See
docs/hil.md for every key.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hil.faults import Fault, faults_from_tables
from hil.moving_obstacles import MovingObstacle
from hil.rangefinder_sim import DEFAULT_YAWS_DEG, yaw_ring
from hil.scenario_placement import check_clear_of_obstacles
from logs.file_kinds import SCENARIO, refuse_another_kind
from logs.metrics import DEFAULT_ENCOUNTER_MARGIN_M
from logs.settings import MAX_SEED, Table, finite_float, parse_toml, read_settings_text, shown
from navigator.map_config import terrain_from_table
from navigator.scan_tracker_config import MAX_MOUNT_OFFSET_M
from navigator.sensor_mount import SensorMount
from navigator.terrain import TerrainMap, disc_mask
from navigator.terrain_class_settings import (
    PHYSICS_FIELDS,
    SCENARIO_REFUSALS,
    ClassOverrides,
    overrides_from_table,
    with_overrides,
)
from navigator.terrain_classes import TerrainClass


@dataclass(frozen=True)
class Obstacle:
    id: str
    x: float
    y: float
    radius_m: float
    known: bool = True  # on the rover's map from the start; unknown ones must be perceived


@dataclass(frozen=True)
class Goal:
    x: float
    y: float
    tolerance_m: float


PERCEPTION_MODELS = ("objects", "scan", "rangefinders")
# Perception that reaches the onboard stack as MAVLink messages (the rest: objects handed over in process).
MAVLINK_PERCEPTION = ("scan", "rangefinders")


@dataclass(frozen=True)
class SensorSettings:
    gps_rate_hz: float = 5.0
    gps_noise_m: float = 0.5
    gps_latency_s: float = 0.0
    gps_dropout_probability: float = 0.0
    gps_satellites: int = 12
    imu_rate_hz: float = 50.0
    gyro_noise_rps: float = 0.005
    accel_noise_mps2: float = 0.05
    gyro_bias_rps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_bias_mps2: tuple[float, float, float] = (0.0, 0.0, 0.0)
    perception_range_m: float = 8.0
    perception_rate_hz: float = 10.0
    perception_noise_m: float = 0.0
    # How the rover perceives obstacles (PERCEPTION_MODELS): "objects" hands the onboard stack each obstacle
    # within range as it is (id, disc, velocity); "scan" sends a simulated lidar's scans over MAVLink
    # (hil.lidar_sim) and the stack tracks obstacles from them, as `rover run` does on the rover;
    # "rangefinders" has the autopilot send a ring of single-beam rangefinders' DISTANCE_SENSOR readings
    # (hil.rangefinder_sim), tracked the same way.
    perception: str = "objects"
    perception_fov_deg: float = 360.0  # the simulated lidar's field of view, centred on its front
    # Where the simulated lidar sits on the rover ("scan" only): forward and left of the body's reference
    # point (m), and its front from the rover's (deg, counter-clockwise). The stack is told separately, in
    # the rover config's [perception] mount_* keys, as a real rover's would be (a lockstep trial's
    # --config; the real-time peer writes them into the rover-hil.toml it leaves for `rover run`).
    perception_mount_forward_m: float = 0.0
    perception_mount_left_m: float = 0.0
    perception_mount_yaw_deg: float = 0.0
    # The ring ("rangefinders" only): each sensor's direction, degrees clockwise from the rover's front as
    # MAV_SENSOR_ROTATION_YAW_<n> names it (its id is its place in the list), and the cone's width. They
    # sit at perception_mount_forward_m / _left_m; range, rate and noise are the perception_* ones.
    rangefinder_yaw_deg: tuple[int, ...] = DEFAULT_YAWS_DEG
    rangefinder_fov_deg: float = 15.0
    # Or each sensor on its own ([sensors] rangefinders = [{yaw_deg, forward_m, left_m}, ...]): where it
    # sits and faces, any direction; None: the ring above.
    rangefinder_mounts: tuple[SensorMount, ...] | None = None

    @property
    def rangefinder_ring(self) -> tuple[SensorMount, ...]:
        """Where each simulated rangefinder sits and faces, by id (its place in the tuple)."""
        if self.rangefinder_mounts is not None:
            return self.rangefinder_mounts
        return yaw_ring(self.rangefinder_yaw_deg, self.lidar_mount)

    @property
    def lidar_mount(self) -> SensorMount:
        return SensorMount(
            self.perception_mount_forward_m,
            self.perception_mount_left_m,
            math.radians(self.perception_mount_yaw_deg),
        )

    @classmethod
    def from_table(cls, table: Table) -> SensorSettings:
        gyro_bias = table.numbers("gyro_bias_rps", list(cls.gyro_bias_rps), length=3)
        accel_bias = table.numbers("accel_bias_mps2", list(cls.accel_bias_mps2), length=3)
        settings = cls(
            gps_rate_hz=table.number("gps_rate_hz", cls.gps_rate_hz, lo=0.1, hi=50.0),
            gps_noise_m=table.number("gps_noise_m", cls.gps_noise_m, lo=0.0, hi=50.0),
            gps_latency_s=table.number("gps_latency_s", cls.gps_latency_s, lo=0.0, hi=5.0),
            gps_dropout_probability=table.number(
                "gps_dropout_probability", cls.gps_dropout_probability, lo=0.0, hi=1.0
            ),
            gps_satellites=table.integer("gps_satellites", cls.gps_satellites, lo=0, hi=64),
            imu_rate_hz=table.number("imu_rate_hz", cls.imu_rate_hz, lo=1.0, hi=1000.0),
            gyro_noise_rps=table.number("gyro_noise_rps", cls.gyro_noise_rps, lo=0.0, hi=1.0),
            accel_noise_mps2=table.number("accel_noise_mps2", cls.accel_noise_mps2, lo=0.0, hi=10.0),
            gyro_bias_rps=(gyro_bias[0], gyro_bias[1], gyro_bias[2]),
            accel_bias_mps2=(accel_bias[0], accel_bias[1], accel_bias[2]),
            perception_range_m=table.number("perception_range_m", cls.perception_range_m, lo=0.1, hi=500.0),
            perception_rate_hz=table.number("perception_rate_hz", cls.perception_rate_hz, lo=0.1, hi=100.0),
            perception_noise_m=table.number("perception_noise_m", cls.perception_noise_m, lo=0.0, hi=10.0),
            perception=table.text("perception", cls.perception, choices=PERCEPTION_MODELS),
            perception_fov_deg=table.number("perception_fov_deg", cls.perception_fov_deg, lo=1.0, hi=360.0),
            perception_mount_forward_m=table.number(
                "perception_mount_forward_m",
                cls.perception_mount_forward_m,
                lo=-MAX_MOUNT_OFFSET_M,
                hi=MAX_MOUNT_OFFSET_M,
            ),
            perception_mount_left_m=table.number(
                "perception_mount_left_m",
                cls.perception_mount_left_m,
                lo=-MAX_MOUNT_OFFSET_M,
                hi=MAX_MOUNT_OFFSET_M,
            ),
            perception_mount_yaw_deg=table.number(
                "perception_mount_yaw_deg", cls.perception_mount_yaw_deg, lo=-180.0, hi=180.0
            ),
            rangefinder_yaw_deg=_rangefinder_yaws(table),
            rangefinder_fov_deg=table.number("rangefinder_fov_deg", cls.rangefinder_fov_deg, lo=0.0, hi=90.0),
            rangefinder_mounts=_rangefinder_mounts(table),
        )
        if settings.perception == "rangefinders" and settings.perception_mount_yaw_deg != 0.0:
            raise table.error(
                "perception_mount_yaw_deg",
                "turns the lidar; a rangefinder faces where its rangefinder_yaw_deg or rangefinders entry "
                "says",
            )
        table.finish()
        return settings


MAX_RANGEFINDERS = 16


def _rangefinder_mounts(table: Table) -> tuple[SensorMount, ...] | None:
    """``rangefinders = [{yaw_deg = 30.0, forward_m = 0.4, left_m = 0.2}, ...]``: each sensor's direction
    (degrees counter-clockwise from the rover's front, as ``perception_mount_yaw_deg`` and the rover config
    count) and place (m; default the perception_mount_* point), each sensor once; ids by order. None when
    not given (the ``rangefinder_yaw_deg`` ring, whose directions count clockwise as MAVLink names them)."""
    if not table.has("rangefinders"):
        return None
    if table.has("rangefinder_yaw_deg"):
        raise table.error("rangefinders", "give rangefinders or rangefinder_yaw_deg, not both")
    entries = table.tables("rangefinders")
    if not 1 <= len(entries) <= MAX_RANGEFINDERS:
        raise table.error("rangefinders", f"1 to {MAX_RANGEFINDERS} sensors, got {len(entries)}")
    forward = table.number("perception_mount_forward_m", 0.0)
    left = table.number("perception_mount_left_m", 0.0)
    mounts: list[SensorMount] = []
    for index, entry in enumerate(entries):
        yaw_deg = entry.number("yaw_deg", lo=-360.0, hi=360.0)
        mount = SensorMount(
            entry.number("forward_m", forward, lo=-MAX_MOUNT_OFFSET_M, hi=MAX_MOUNT_OFFSET_M),
            entry.number("left_m", left, lo=-MAX_MOUNT_OFFSET_M, hi=MAX_MOUNT_OFFSET_M),
            math.radians(_half_turns(yaw_deg)),
        )
        entry.finish()
        if mount in mounts:
            raise table.error(
                "rangefinders", f"sensor {index} is sensor {mounts.index(mount)} again: same place, same way"
            )
        mounts.append(mount)
    return tuple(mounts)


def _half_turns(yaw_deg: float) -> float:
    """``yaw_deg`` in (-180, 180]: one number for each direction (-180 is 180), so two sensors the same way
    compare equal."""
    wrapped = math.remainder(yaw_deg, 360.0)
    return 180.0 if wrapped == -180.0 else wrapped


def _rangefinder_yaws(table: Table) -> tuple[int, ...]:
    yaws = table.integers("rangefinder_yaw_deg", list(DEFAULT_YAWS_DEG))
    if not 1 <= len(yaws) <= 8 or any(yaw % 45 or not 0 <= yaw < 360 for yaw in yaws):
        raise table.error(
            "rangefinder_yaw_deg",
            f"1 to 8 directions, each a multiple of 45 in [0, 315] (clockwise), got {yaws}",
        )
    if len(set(yaws)) != len(yaws):
        raise table.error("rangefinder_yaw_deg", f"a direction is listed twice: {yaws}")
    return tuple(yaws)


@dataclass(frozen=True)
class SuccessCriteria:
    """What a trial must achieve to count as a success (checked against its metrics)."""

    goal_reached: bool = True
    max_rollovers: int = 0
    max_collisions: int | None = None  # None: not checked
    min_path_accuracy_pct: float | None = None
    max_duration_s: float | None = None
    # Checked on the ground truth, unlike goal_reached (the rover's own ARRIVED, judged on its estimate).
    max_final_distance_m: float | None = None

    @classmethod
    def from_table(cls, table: Table) -> SuccessCriteria:
        criteria = cls(
            goal_reached=table.flag("goal_reached", True),
            max_rollovers=table.integer("max_rollovers", 0, lo=0),
            max_collisions=table.integer("max_collisions", lo=0) if table.has("max_collisions") else None,
            min_path_accuracy_pct=(
                table.number("min_path_accuracy_pct", lo=0.0, hi=100.0)
                if table.has("min_path_accuracy_pct")
                else None
            ),
            max_duration_s=(table.number("max_duration_s", lo=0.0) if table.has("max_duration_s") else None),
            max_final_distance_m=(
                table.number("max_final_distance_m", lo=0.0) if table.has("max_final_distance_m") else None
            ),
        )
        table.finish()
        return criteria


@dataclass(frozen=True)
class Scenario:
    name: str
    source: str
    text: str  # the file as written, attached to every recording
    terrain: TerrainMap  # the true world, static obstacles included
    believed_terrain: TerrainMap  # the rover's map: the true ground with the *known* obstacles only
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
    moving_obstacles: tuple[MovingObstacle, ...] = ()
    faults: tuple[Fault, ...] = ()
    success: SuccessCriteria = SuccessCriteria()
    # An obstacle whose edge came this close to the track was "in the way" (docs/metrics.md).
    encounter_margin_m: float = DEFAULT_ENCOUNTER_MARGIN_M
    # [terrain_classes.<name>] as written: the true world's ground where it is not the built-in table's.
    terrain_classes: ClassOverrides = field(default_factory=dict)

    @property
    def classes(self) -> dict[int, TerrainClass]:
        """The terrain classes the true world is made of (the simulator's); the planner's beliefs are the
        rover config's (``RoverConfig.classes``)."""
        return with_overrides(self.terrain_classes)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file; raises ``ConfigError`` naming the file and the key."""
    text = read_settings_text(path)  # read once: the table and the recorded text are the same bytes
    return scenario_from_table(parse_toml(text, str(path)), text, base_dir=Path(path).parent)


def scenario_from_table(root: Table, text: str, base_dir: Path) -> Scenario:
    refuse_another_kind(root, SCENARIO)
    name = root.text("name")
    root.text("description", "")
    duration_s = root.number("duration_s", 120.0, lo=1.0, hi=24 * 3600.0)
    seed = root.integer("seed", 0, lo=0, hi=MAX_SEED)
    path_tolerance_m = root.number("path_tolerance_m", 0.5, lo=0.01, hi=100.0)
    encounter_margin_m = root.number("encounter_margin_m", DEFAULT_ENCOUNTER_MARGIN_M, hi=100.0)
    if encounter_margin_m <= 0.0:
        raise root.error("encounter_margin_m", f"must be > 0 m, got {encounter_margin_m}")
    datum_values = root.numbers("datum", [47.397742, 8.545594, 488.0], length=3)
    if not (-90.0 <= datum_values[0] <= 90.0 and -180.0 <= datum_values[1] <= 180.0):
        raise root.error(
            "datum", f"latitude must be in [-90, 90] and longitude in [-180, 180], got {datum_values}"
        )
    tags = _tags(root)

    terrain, summary = terrain_from_table(root.table("terrain"), base_dir)

    start_table = root.table("start")
    start_xy = start_table.point("xy")
    start_yaw = math.radians(start_table.number("yaw_deg", 0.0, lo=-360.0, hi=360.0))
    start_table.finish()
    _check_inside(terrain, start_xy, start_table, "xy")

    goals = []
    goal_tables = root.tables("goals", optional=False)
    for goal_table in goal_tables:
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
        known = obstacle_table.flag("known", True)
        obstacle_table.finish()
        obstacles.append(Obstacle(obstacle_id, xy[0], xy[1], radius, known))
    check_clear_of_obstacles(terrain, obstacles, start_xy, start_table, "xy")
    for goal, goal_table in zip(goals, goal_tables, strict=True):
        check_clear_of_obstacles(terrain, obstacles, (goal.x, goal.y), goal_table, "xy")
    believed_terrain = terrain.with_obstacles(_discs(terrain, [o for o in obstacles if o.known]))
    terrain = terrain.with_obstacles(_discs(terrain, obstacles))

    moving = []
    for index, moving_table in enumerate(root.tables("moving_obstacles")):
        moving_id = moving_table.text("id", f"mover{index}")
        if moving_id in seen_ids:
            raise moving_table.error("id", f"duplicate obstacle id {moving_id!r}")
        seen_ids.add(moving_id)
        waypoints = _waypoints(moving_table, terrain)
        radius_m = moving_table.number("radius_m", lo=0.05, hi=50.0)
        speed_mps = moving_table.number("speed_mps", lo=0.0, hi=20.0)
        start_s = moving_table.number("start_s", 0.0, lo=0.0)
        if start_s >= duration_s:
            # As for a fault: one the trial never runs is a mistake in the file (start_s in ms, say).
            raise moving_table.error(
                "start_s",
                f"{start_s:g} s is not before the scenario's duration_s {duration_s:g} s: the obstacle would "
                "never move",
            )
        moving.append(MovingObstacle(moving_id, radius_m, waypoints, speed_mps, start_s))
        moving_table.finish()

    sensors = SensorSettings.from_table(root.table("sensors", optional=True))
    faults = faults_from_tables(root.tables("faults"), duration_s)
    success = SuccessCriteria.from_table(root.table("success", optional=True))
    terrain_classes = overrides_from_table(root, PHYSICS_FIELDS, SCENARIO_REFUSALS)
    root.finish()
    return Scenario(
        name=name,
        source=root.source,
        text=text,
        terrain=terrain,
        believed_terrain=believed_terrain,
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
        moving_obstacles=tuple(moving),
        faults=faults,
        success=success,
        encounter_margin_m=encounter_margin_m,
        terrain_classes=terrain_classes,
    )


def _tags(root: Table) -> tuple[str, ...]:
    tags = root.raw("tags", [])
    if not isinstance(tags, list) or not all(isinstance(tag, str) for tag in tags):
        raise root.error("tags", f'expected a list of strings, e.g. tags = ["sandy"], got {tags!r}')
    return tuple(tags)


def _discs(terrain: TerrainMap, obstacles: list[Obstacle]) -> np.ndarray:
    mask = np.zeros(terrain.shape, dtype=bool)
    for obstacle in obstacles:
        mask |= disc_mask(terrain, obstacle.x, obstacle.y, obstacle.radius_m)
    return mask


def _waypoints(table: Table, terrain: TerrainMap) -> tuple[tuple[float, float], ...]:
    raw = table.raw("waypoints")
    if not isinstance(raw, list) or len(raw) < 2:
        raise table.error("waypoints", f"need a list of at least two [x, y] points, got {raw!r}")
    points = []
    for index, point in enumerate(raw):
        if not isinstance(point, list) or len(point) != 2 or any(finite_float(v) is None for v in point):
            raise table.error("waypoints", f"point {index} must be [x, y] in metres, got {shown(point)}")
        xy = (float(point[0]), float(point[1]))
        if not terrain.contains(*xy):
            raise table.error("waypoints", f"point {index} {xy} lies outside the terrain map")
        points.append(xy)
    return tuple(points)


def _check_inside(terrain: TerrainMap, xy: tuple[float, float], table: Table, key: str) -> None:
    if not terrain.contains(*xy):
        raise table.error(key, f"point {xy} lies outside the terrain map")


def with_perception(scenario: Scenario, perception: str | None) -> Scenario:
    """``scenario`` with its rover perceiving obstacles as ``perception`` says (``PERCEPTION_MODELS``; None:
    unchanged): a campaign variant's choice, or the real-time peer's, which has only its lidar."""
    if perception is None or perception == scenario.sensors.perception:
        return scenario
    if perception not in PERCEPTION_MODELS:
        raise ValueError(f"perception must be one of {PERCEPTION_MODELS}, got {perception!r}")
    return dataclasses.replace(scenario, sensors=dataclasses.replace(scenario.sensors, perception=perception))
