"""The rover's oriented-rectangle footprint against the obstacle cells of a terrain map.

The rectangle is ``footprint_length_m`` (along the heading) by ``footprint_width_m``, centred on the pose.
It collides with an obstacle cell when the two overlap with positive area (touching edges do not count),
decided exactly by the separating-axis test on the four axes that matter (the map's x and y, the rover's
forward and left). With ``edge_is_obstacle`` any part of it off the map collides too, like the planner's
inflation and the simulator's boundary contact.

``rectangle_contact`` is the same test for one pose on the unpadded obstacle layer, telling obstacle from map
edge (the simulator's contact test, every physics step).

Walking a path (``first_collision``) samples it: poses every ``step_m`` along each segment with the
segment's heading (the path tangent), and at each corner the turn on the spot from the incoming to the
outgoing heading every ``turn_step_rad`` (a skid-steer rover turns in place). Between samples a corner of
the rectangle moves at most ``step_m`` or ``circumscribed radius x turn_step_rad``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from navigator.errors import ParameterError
from navigator.terrain import TerrainMap
from navigator.vehicle import VehicleParams

DEFAULT_TURN_STEP_RAD = math.radians(5.0)


@dataclass(frozen=True)
class Footprint:
    """A ``length_m`` (forward) x ``width_m`` (sideways) rectangle centred on the pose."""

    length_m: float
    width_m: float

    def __post_init__(self) -> None:
        for name in ("length_m", "width_m"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
                raise ParameterError(f"footprint {name} must be a finite number > 0, got {value!r}")

    @classmethod
    def of(cls, params: VehicleParams) -> Footprint:
        return cls(params.footprint_length_m, params.footprint_width_m)

    @property
    def inscribed_radius_m(self) -> float:
        """The largest circle inside the rectangle: inflating by it is optimistic (misses the corners)."""
        return 0.5 * min(self.length_m, self.width_m)

    @property
    def circumscribed_radius_m(self) -> float:
        """The circle through the corners: inflating by it is pessimistic (blocks lengthwise squeezes)."""
        return 0.5 * math.hypot(self.length_m, self.width_m)


@dataclass(frozen=True)
class Collision:
    """The first colliding pose along a path: ``index`` of the segment (points[index] -> points[index+1]),
    ``distance_m`` along the path, the pose and the obstacle cells it overlaps (``(k, 2)`` rows, cols;
    cells off the map, i.e. the map edge, have row or col -1 or rows/cols)."""

    index: int
    distance_m: float
    x: float
    y: float
    yaw: float
    cells: np.ndarray


def footprint_collides(
    terrain: TerrainMap,
    pose: tuple[float, float, float],
    footprint: Footprint,
    *,
    edge_is_obstacle: bool = True,
) -> bool:
    """Whether the rectangle at ``pose`` = (x, y, yaw) (ENU metres, rad from east) overlaps an obstacle."""
    poses = np.array([pose], dtype=np.float64)
    return _first_hit(terrain, poses, footprint, edge_is_obstacle) >= 0


def overlapped_cells(
    terrain: TerrainMap,
    pose: tuple[float, float, float],
    footprint: Footprint,
    *,
    edge_is_obstacle: bool = True,
) -> np.ndarray:
    """Obstacle cells ``(k, 2)`` (row, col) the rectangle overlaps; the map edge as cells just off the map."""
    grid, (ox, oy) = _padded(terrain, edge_is_obstacle)
    x, y, yaw = pose
    res = terrain.resolution_m
    half_length, half_width, half_cell = 0.5 * footprint.length_m, 0.5 * footprint.width_m, 0.5 * res
    # Only cells within the circumscribed radius (plus a cell) can overlap: scan that window.
    reach = footprint.circumscribed_radius_m + res
    row0, row1 = (max(0, math.floor((y + sign * reach - oy) / res)) for sign in (-1.0, 1.0))
    col0, col1 = (max(0, math.floor((x + sign * reach - ox) / res)) for sign in (-1.0, 1.0))
    rows, cols = np.nonzero(grid[row0 : row1 + 1, col0 : col1 + 1])
    rows, cols = rows + row0, cols + col0
    dx = ox + (cols + 0.5) * res - x
    dy = oy + (rows + 0.5) * res - y
    cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
    abs_c, abs_s = abs(cos_yaw), abs(sin_yaw)
    cell_reach = half_cell * (abs_c + abs_s)
    # The separating-axis test of ``_rect_overlaps_cell``, over all candidate cells at once.
    hit = (
        (np.abs(dx) < half_cell + half_length * abs_c + half_width * abs_s)
        & (np.abs(dy) < half_cell + half_length * abs_s + half_width * abs_c)
        & (np.abs(dx * cos_yaw + dy * sin_yaw) < half_length + cell_reach)
        & (np.abs(-dx * sin_yaw + dy * cos_yaw) < half_width + cell_reach)
    )
    shift = 1 if edge_is_obstacle else 0
    return np.column_stack([rows[hit], cols[hit]]).astype(np.int64) - shift


def path_poses(
    points: np.ndarray,
    step_m: float,
    turn_step_rad: float = DEFAULT_TURN_STEP_RAD,
    start_yaw: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sampled poses along a polyline: ``(poses (n, 3), segment index (n,), distance along (n,))``.

    Each segment contributes poses from its start to its end (inclusive) every ``step_m`` or closer, at
    its heading; before a segment whose heading differs from the previous one (or from ``start_yaw``),
    the turn on the spot at its start point. Zero-length segments are skipped.
    """
    path = np.asarray(points, dtype=np.float64)
    if path.ndim != 2 or path.shape[1] != 2 or path.shape[0] < 1 or not np.all(np.isfinite(path)):
        raise ParameterError(f"a path must be (n, 2) finite points, got shape {path.shape}")
    if not (step_m > 0.0 and turn_step_rad > 0.0):
        raise ParameterError("path sampling steps must be > 0")
    poses: list[np.ndarray] = []
    segments: list[np.ndarray] = []
    distances: list[np.ndarray] = []
    heading = start_yaw
    travelled = 0.0
    for index in range(path.shape[0] - 1):
        (x0, y0), (x1, y1) = path[index], path[index + 1]
        length = math.hypot(x1 - x0, y1 - y0)
        if length == 0.0:
            continue
        yaw = math.atan2(y1 - y0, x1 - x0)
        if heading is not None:
            turn = math.remainder(yaw - heading, math.tau)
            count = math.ceil(abs(turn) / turn_step_rad)
            if count:
                angles = heading + turn * np.arange(count) / count
                poses.append(np.column_stack([np.full(count, x0), np.full(count, y0), angles]))
                segments.append(np.full(count, index))
                distances.append(np.full(count, travelled))
        count = max(1, math.ceil(length / step_m))
        t = np.arange(count + 1) / count
        poses.append(np.column_stack([x0 + t * (x1 - x0), y0 + t * (y1 - y0), np.full(count + 1, yaw)]))
        segments.append(np.full(count + 1, index))
        distances.append(travelled + t * length)
        heading = yaw
        travelled += length
    if not poses:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64), np.zeros(0)
    return np.concatenate(poses), np.concatenate(segments).astype(np.int64), np.concatenate(distances)


def first_collision(
    points: np.ndarray,
    terrain: TerrainMap,
    footprint: Footprint,
    *,
    step_m: float | None = None,
    turn_step_rad: float = DEFAULT_TURN_STEP_RAD,
    start_yaw: float | None = None,
    skip_m: float = 0.0,
    edge_is_obstacle: bool = True,
) -> Collision | None:
    """The first pose along ``points`` (``(n, 2)`` ENU metres) whose rectangle hits an obstacle, or None.

    ``step_m`` defaults to a quarter cell. Poses less than ``skip_m`` along the path are not checked (where
    the rover already is: its start pose is a fact, not a plan).
    """
    step = 0.25 * terrain.resolution_m if step_m is None else step_m
    poses, segments, distances = path_poses(points, step, turn_step_rad, start_yaw)
    keep = distances >= skip_m
    poses, segments, distances = poses[keep], segments[keep], distances[keep]
    hit = _first_hit(terrain, poses, footprint, edge_is_obstacle)
    if hit < 0:
        return None
    x, y, yaw = (float(v) for v in poses[hit])
    cells = overlapped_cells(terrain, (x, y, yaw), footprint, edge_is_obstacle=edge_is_obstacle)
    return Collision(int(segments[hit]), float(distances[hit]), x, y, yaw, cells)


def _padded(terrain: TerrainMap, edge_is_obstacle: bool) -> tuple[np.ndarray, tuple[float, float]]:
    """The obstacle grid, with a ring of obstacle cells just off the map standing for its edge."""
    ox, oy = terrain.origin_xy
    if not edge_is_obstacle:
        return np.ascontiguousarray(terrain.obstacles), (ox, oy)
    res = terrain.resolution_m
    return np.pad(terrain.obstacles, 1, constant_values=True), (ox - res, oy - res)


def _first_hit(terrain: TerrainMap, poses: np.ndarray, footprint: Footprint, edge_is_obstacle: bool) -> int:
    grid, (ox, oy) = _padded(terrain, edge_is_obstacle)
    return int(
        _first_hit_kernel(
            grid, terrain.resolution_m, ox, oy, np.ascontiguousarray(poses, dtype=np.float64),
            0.5 * footprint.length_m, 0.5 * footprint.width_m, edge_is_obstacle,
        )
    )  # fmt: skip


@numba.njit(cache=True)
def _rect_overlaps_cell(
    dx: float,
    dy: float,
    cos_yaw: float,
    sin_yaw: float,
    half_length: float,
    half_width: float,
    half_cell: float,
) -> bool:
    """Separating-axis test: rectangle centred at the origin vs the axis-aligned square centred at (dx, dy).

    Two convex polygons overlap (with positive area) iff no edge normal of either separates them; here the
    normals are the map's x and y (the cell) and the rover's forward and left axes (the rectangle).
    """
    abs_c, abs_s = abs(cos_yaw), abs(sin_yaw)
    if abs(dx) >= half_cell + half_length * abs_c + half_width * abs_s:
        return False
    if abs(dy) >= half_cell + half_length * abs_s + half_width * abs_c:
        return False
    cell_reach = half_cell * (abs_c + abs_s)  # the square's half extent along a rotated axis
    if abs(dx * cos_yaw + dy * sin_yaw) >= half_length + cell_reach:
        return False
    return abs(-dx * sin_yaw + dy * cos_yaw) < half_width + cell_reach


@numba.njit(cache=True)
def rectangle_reach(
    cos_yaw: float, sin_yaw: float, half_length: float, half_width: float
) -> tuple[float, float]:
    """Half extents (x, y) of the rectangle's axis-aligned bounding box: attained at its corners, so the
    rectangle reaches past a line of constant x or y exactly when the box does."""
    reach_x = half_length * abs(cos_yaw) + half_width * abs(sin_yaw)
    reach_y = half_length * abs(sin_yaw) + half_width * abs(cos_yaw)
    return reach_x, reach_y


@numba.njit(cache=True)
def _hits_cells(
    grid: np.ndarray,
    res: float,
    ox: float,
    oy: float,
    x: float,
    y: float,
    cos_yaw: float,
    sin_yaw: float,
    half_length: float,
    half_width: float,
) -> bool:
    """Whether the rectangle at (x, y) overlaps a True cell of ``grid`` (only cells in its bounding box)."""
    rows, cols = grid.shape
    half_cell = 0.5 * res
    reach_x, reach_y = rectangle_reach(cos_yaw, sin_yaw, half_length, half_width)
    col0 = max(0, math.floor((x - reach_x - ox) / res))
    col1 = min(cols - 1, math.floor((x + reach_x - ox) / res))
    row0 = max(0, math.floor((y - reach_y - oy) / res))
    row1 = min(rows - 1, math.floor((y + reach_y - oy) / res))
    for row in range(row0, row1 + 1):
        dy = oy + (row + 0.5) * res - y
        for col in range(col0, col1 + 1):
            if grid[row, col] and _rect_overlaps_cell(
                ox + (col + 0.5) * res - x, dy, cos_yaw, sin_yaw, half_length, half_width, half_cell
            ):
                return True
    return False


@numba.njit(cache=True)
def _first_hit_kernel(
    grid: np.ndarray,
    res: float,
    ox: float,
    oy: float,
    poses: np.ndarray,
    half_length: float,
    half_width: float,
    edge: bool,
) -> int:
    """Index of the first pose whose rectangle overlaps a True cell of ``grid``, or -1.

    With ``edge``, ``grid`` carries a ring of True cells around the map and any pose reaching past the map
    (the rectangle's bounding box is attained at its corners, so this is exact) collides too, even far off.
    """
    rows, cols = grid.shape
    ring = 1 if edge else 0
    x_lo, x_hi = ox + ring * res, ox + (cols - ring) * res
    y_lo, y_hi = oy + ring * res, oy + (rows - ring) * res
    for index in range(poses.shape[0]):
        x, y, yaw = poses[index, 0], poses[index, 1], poses[index, 2]
        cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
        reach_x, reach_y = rectangle_reach(cos_yaw, sin_yaw, half_length, half_width)
        if edge and (x - reach_x < x_lo or x + reach_x > x_hi or y - reach_y < y_lo or y + reach_y > y_hi):
            return index
        if _hits_cells(grid, res, ox, oy, x, y, cos_yaw, sin_yaw, half_length, half_width):
            return index
    return -1


# What ``rectangle_contact`` found.
CLEAR, OBSTACLE, BOUNDARY = 0, 1, 2


@numba.njit(cache=True)
def rectangle_contact(
    obstacles: np.ndarray,
    res: float,
    ox: float,
    oy: float,
    x: float,
    y: float,
    yaw: float,
    half_length: float,
    half_width: float,
) -> int:
    """One pose of a ``2 half_length`` x ``2 half_width`` rectangle against a map's obstacle layer
    (``obstacles`` unpadded, its lower-left corner at (ox, oy)): ``BOUNDARY`` when any part of it is off the
    map, else ``OBSTACLE`` when it overlaps an obstacle cell (positive area, as ``footprint_collides``),
    else ``CLEAR``. The same exact test the planner runs, for one pose without building a padded grid."""
    rows, cols = obstacles.shape
    cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
    reach_x, reach_y = rectangle_reach(cos_yaw, sin_yaw, half_length, half_width)
    if x - reach_x < ox or x + reach_x > ox + cols * res or y - reach_y < oy or y + reach_y > oy + rows * res:
        return BOUNDARY
    if _hits_cells(obstacles, res, ox, oy, x, y, cos_yaw, sin_yaw, half_length, half_width):
        return OBSTACLE
    return CLEAR


def disc_gap_m(
    pose: tuple[float, float, float], footprint: Footprint, centre: tuple[float, float], radius_m: float
) -> float:
    """Distance from the rectangle at ``pose`` to a disc (< 0: they overlap; inside the rectangle it is
    ``-radius_m``): the disc centre in body axes, clamped to the rectangle, is the nearest point."""
    x, y, yaw = pose
    dx, dy = centre[0] - x, centre[1] - y
    forward = dx * math.cos(yaw) + dy * math.sin(yaw)
    left = -dx * math.sin(yaw) + dy * math.cos(yaw)
    outside_forward = max(abs(forward) - 0.5 * footprint.length_m, 0.0)
    outside_left = max(abs(left) - 0.5 * footprint.width_m, 0.0)
    return math.hypot(outside_forward, outside_left) - radius_m
