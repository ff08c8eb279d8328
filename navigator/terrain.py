"""The terrain map: elevation, terrain class and obstacle layers on one regular grid in local ENU.

Cell ``(row, col)`` covers ``x in [ox + col*res, ox + (col+1)*res)`` and ``y in [oy + row*res, ...)``:
rows run north (y), columns run east (x), and row 0 is the southern edge. Elevation samples sit at cell
centres; between centres it is bilinear.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from navigator.errors import TerrainError
from navigator.ground_kernel import GroundUnder, ground_at_kernel
from navigator.layer_checks import Layer, check_one_grid, checked_layer
from navigator.terrain_classes import TERRAIN_CLASSES

MAZE_WALL = 1
MAZE_OPEN = 2

# The most cells a map may have: 4096 x 4096, a 1 km square at 0.25 m. Planning on a map costs about
# 200 bytes a cell at its peak (layers, slope gradients, eight direction-cost factors, the cost-to-go
# field; measured ~210 B/cell on a 2048 x 2048 map), so this bound is ~3.5 GB: what a companion computer
# with 8 GB can still hold next to the rest of the stack. A size past it is a typo in a size or a
# resolution, and is refused before anything is allocated instead of ending in a MemoryError.
MAX_MAP_CELLS = 4096 * 4096


def check_map_cells(rows: int, cols: int, what: str, remedy: str, *, key: str | None = None) -> None:
    """TerrainError (naming ``key``) when a ``rows`` x ``cols`` map would exceed ``MAX_MAP_CELLS``.

    ``what``: the input that asks for that size; ``remedy``: what the user can change."""
    cells = rows * cols
    if cells > MAX_MAP_CELLS:
        raise TerrainError(
            f"{what} would need {rows:,} x {cols:,} = {cells:,} cells; a map may have at most "
            f"{MAX_MAP_CELLS:,} (planning takes ~200 bytes a cell): {remedy}",
            key=key,
        )


def _frozen(array: np.ndarray) -> np.ndarray:
    copy = np.array(array, copy=True)
    copy.setflags(write=False)
    return copy


@dataclass(frozen=True, eq=False)
class TerrainMap:
    """Immutable terrain layers; construct through the loaders or directly (validated either way).

    Layers (all ``(rows, cols)``): ``elevation_m`` float64 metres up, ``terrain_class`` uint8 ids from
    ``TERRAIN_CLASSES``, ``obstacles`` bool (True = something the rover must not touch).
    """

    elevation_m: np.ndarray
    terrain_class: np.ndarray
    obstacles: np.ndarray
    resolution_m: float
    origin_xy: tuple[float, float] = (0.0, 0.0)
    _grad_x: np.ndarray = field(init=False, repr=False)
    _grad_y: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.resolution_m, int | float) or not (
            math.isfinite(self.resolution_m) and self.resolution_m > 0.0
        ):
            raise TerrainError(f"terrain resolution_m must be a finite number > 0, got {self.resolution_m!r}")
        if len(self.origin_xy) != 2 or not all(math.isfinite(float(v)) for v in self.origin_xy):
            raise TerrainError(f"terrain origin_xy must be two finite numbers, got {self.origin_xy!r}")
        # The same check as the layer files get (navigator.layer_checks), naming the field instead of a file.
        layers = [
            (Layer.array("elevation", "elevation"), np.asarray(self.elevation_m)),
            (Layer.array("classes", "terrain_class"), np.asarray(self.terrain_class)),
            (Layer.array("obstacles", "obstacles"), np.asarray(self.obstacles)),
        ]
        elevation, classes, obstacles = (checked_layer(values, layer) for layer, values in layers)
        check_one_grid([(layer, values.shape) for layer, values in layers])
        set_ = object.__setattr__  # frozen dataclass: normalise the layers once, here
        set_(self, "resolution_m", float(self.resolution_m))
        set_(self, "origin_xy", (float(self.origin_xy[0]), float(self.origin_xy[1])))
        set_(self, "elevation_m", _frozen(elevation))
        set_(self, "terrain_class", _frozen(classes))
        set_(self, "obstacles", _frozen(obstacles))
        grad_y, grad_x = _gradient(elevation, self.resolution_m)
        set_(self, "_grad_x", _frozen(grad_x))
        set_(self, "_grad_y", _frozen(grad_y))

    # --- geometry ---------------------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        rows, cols = self.elevation_m.shape
        return int(rows), int(cols)

    @property
    def size_m(self) -> tuple[float, float]:
        """(width east, height north) in metres."""
        rows, cols = self.shape
        return cols * self.resolution_m, rows * self.resolution_m

    def contains(self, x: float, y: float) -> bool:
        width, height = self.size_m
        dx, dy = x - self.origin_xy[0], y - self.origin_xy[1]
        return 0.0 <= dx < width and 0.0 <= dy < height

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell holding the point; TerrainError when it is off the map."""
        if not (math.isfinite(x) and math.isfinite(y)) or not self.contains(x, y):
            width, height = self.size_m
            ox, oy = self.origin_xy
            raise TerrainError(
                f"point ({x:.3f}, {y:.3f}) is off the map, which covers x [{ox:g}, {ox + width:g}) "
                f"and y [{oy:g}, {oy + height:g})"
            )
        rows, cols = self.shape
        col = min(int((x - self.origin_xy[0]) // self.resolution_m), cols - 1)
        row = min(int((y - self.origin_xy[1]) // self.resolution_m), rows - 1)
        return row, col

    def center_of(self, row: int, col: int) -> tuple[float, float]:
        rows, cols = self.shape
        if not (0 <= row < rows and 0 <= col < cols):
            raise TerrainError(f"cell (row {row}, col {col}) is outside the {rows} x {cols} map")
        return (
            self.origin_xy[0] + (col + 0.5) * self.resolution_m,
            self.origin_xy[1] + (row + 0.5) * self.resolution_m,
        )

    # --- queries ----------------------------------------------------------------------------------
    def class_at(self, x: float, y: float) -> int:
        return int(self.terrain_class[self.cell_of(x, y)])

    def elevation_at(self, x: float, y: float) -> float:
        """Bilinear elevation between cell centres (held constant past the outer centres)."""
        return self.ground_at(x, y, 0.0).elevation_m

    def ground_at(self, x: float, y: float, yaw: float) -> GroundUnder:
        """Class, elevation (m) and (roll, pitch) in rad (as ``tilt_at``) at (x, y) for a heading ``yaw``,
        in one compiled call (``navigator.ground_kernel``); TerrainError when the point is off the map."""
        ground = self._ground(x, y, yaw)
        if ground.terrain_class < 0:
            self.cell_of(x, y)  # raises the map's own error, naming the point and the map's extent
        return ground

    def ground_on_map(self, x: float, y: float, yaw: float) -> GroundUnder | None:
        """As ``ground_at``, but None when the point is off the map: the kernel's own ``contains`` test,
        so a caller asking every tick (guidance's speed limits) looks the point up once."""
        ground = self._ground(x, y, yaw)
        return None if ground.terrain_class < 0 else ground

    def ground_under_axles(
        self, x: float, y: float, yaw: float, half_base_m: float
    ) -> tuple[GroundUnder, GroundUnder, GroundUnder] | None:
        """The ground under a rover's rear axle, centre and front axle (``half_base_m`` either side of
        (x, y) along ``yaw``), or None when any of them is off the map: what the learning from the ground
        compares the AHRS's attitude and classes with (``navigator.onboard_learning``)."""
        dx, dy = half_base_m * math.cos(yaw), half_base_m * math.sin(yaw)
        rear = self.ground_on_map(x - dx, y - dy, yaw)
        centre = self.ground_on_map(x, y, yaw)
        front = self.ground_on_map(x + dx, y + dy, yaw)
        if rear is None or centre is None or front is None:
            return None
        return rear, centre, front

    def _ground(self, x: float, y: float, yaw: float) -> GroundUnder:
        """The kernel's answer as it is: class id -1 off the map."""
        return GroundUnder._make(
            ground_at_kernel(
                self.terrain_class, self.elevation_m, self._grad_x, self._grad_y,
                self.origin_xy[0], self.origin_xy[1], self.resolution_m, x, y, yaw,
            )
        )  # fmt: skip

    def slope_gradient(self) -> tuple[np.ndarray, np.ndarray]:
        """(dz/dx, dz/dy) per cell, dimensionless, central differences with spacing ``resolution_m``."""
        return self._grad_x, self._grad_y

    def tilt_at(self, x: float, y: float, yaw: float) -> tuple[float, float]:
        """(roll, pitch) in rad of a rover at (x, y) heading ``yaw``, resting on the local terrain plane.

        With the gradient (bilinear between centres) resolved into a forward slope ``s_f`` and a leftward
        slope ``s_l``: ``pitch = atan(s_f)`` (nose up positive) and
        ``roll = atan2(s_l, sqrt(1 + s_f^2))`` (positive when the ground rises to the left, i.e. the right
        side is lower). These are the exact yaw-pitch-roll angles of a body lying on that plane.
        """
        ground = self.ground_at(x, y, yaw)
        return ground.roll_rad, ground.pitch_rad

    def with_obstacles(self, extra_mask: np.ndarray) -> TerrainMap:
        """A copy with ``extra_mask`` (bool, map shape) added to the obstacle layer.

        The copy shares this map's read-only elevation, class and gradient layers (checked when this map
        was made) rather than validating and copying them again: a planner adds obstacles as they are
        seen, and its cost model recognises the shared layers (``navigator.costs.GroundCost``).
        """
        extra = np.asarray(extra_mask)
        if extra.shape != self.obstacles.shape:
            raise TerrainError(f"obstacle mask has shape {extra.shape}, the map has {self.obstacles.shape}")
        # The fields as __post_init__ left them (the map keeps no other state), without running it again.
        # Field by field, not through ``__dict__``: CPython 3.11 gives an instance whose ``__dict__`` was
        # read a dict of its own, and every attribute load on it then takes twice as long (the world's
        # map is read every physics step).
        copy = object.__new__(type(self))
        for each in fields(self):
            object.__setattr__(copy, each.name, getattr(self, each.name))
        obstacles = self.obstacles | extra.astype(bool)  # a new array, this map's own
        obstacles.setflags(write=False)
        object.__setattr__(copy, "obstacles", obstacles)
        return copy


def _gradient(elevation: np.ndarray, resolution_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(dz/dy, dz/dx); np.gradient needs two samples along an axis, a single row/column is flat."""
    zeros = np.zeros_like(elevation)
    rows, cols = elevation.shape
    grad_y = np.gradient(elevation, resolution_m, axis=0) if rows > 1 else zeros
    grad_x = np.gradient(elevation, resolution_m, axis=1) if cols > 1 else zeros
    return grad_y, grad_x


# --- loaders -------------------------------------------------------------------------------------------
def from_maze(
    matrix: Sequence[Sequence[int]] | np.ndarray,
    cell_size_m: float,
    terrain_class: int = 0,
    *,
    resolution_m: float | None = None,
    origin_xy: tuple[float, float] = (0.0, 0.0),
) -> TerrainMap:
    """The paper's maze (1 = wall, 2 = open) as a flat map; matrix row 0 is the southern edge.

    Each maze cell becomes ``cell_size_m`` of ground, split into grid cells of ``resolution_m``
    (default: one grid cell per maze cell; it must divide ``cell_size_m``).
    """
    try:
        maze = np.array(matrix, dtype=np.int64)
    except (TypeError, ValueError, OverflowError) as err:  # Overflow: an integer past 64 bits
        raise TerrainError(f"maze matrix must be a rectangular list of integers: {err}") from err
    if maze.ndim != 2 or maze.size == 0:
        raise TerrainError(f"maze matrix must be a non-empty rectangle of rows, got shape {maze.shape}")
    bad = ~np.isin(maze, (MAZE_WALL, MAZE_OPEN))
    if np.any(bad):
        row, col = np.argwhere(bad)[0]
        raise TerrainError(
            f"maze cell (row {row}, col {col}) holds {int(maze[row, col])}; "
            f"only {MAZE_WALL} (wall) and {MAZE_OPEN} (open) are allowed"
        )
    if not (math.isfinite(cell_size_m) and cell_size_m > 0.0):
        raise TerrainError(f"maze cell_size_m must be > 0, got {cell_size_m}")
    resolution = cell_size_m if resolution_m is None else resolution_m
    ratio = cell_size_m / resolution if resolution > 0.0 else math.nan
    if not math.isfinite(ratio) or abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        raise TerrainError(
            f"maze resolution_m {resolution_m} must be > 0 and divide cell_size_m {cell_size_m} evenly"
        )
    upsample = round(ratio)
    maze_rows, maze_cols = maze.shape
    check_map_cells(
        maze_rows * upsample,
        maze_cols * upsample,
        f"a {maze_rows} x {maze_cols} maze of {cell_size_m:g} m cells at resolution_m {resolution:g} m",
        f"make resolution_m coarser (each maze cell becomes {upsample} x {upsample} grid cells)"
        if upsample > 1
        else "use a smaller maze matrix",
        key="resolution_m" if upsample > 1 else "matrix",
    )
    walls = np.kron(maze == MAZE_WALL, np.ones((upsample, upsample), dtype=bool))
    return TerrainMap(
        elevation_m=np.zeros(walls.shape),
        terrain_class=np.full(walls.shape, terrain_class, dtype=np.int64),
        obstacles=walls,
        resolution_m=resolution,
        origin_xy=origin_xy,
    )


NPY_MAGIC = b"\x93NUMPY"


def _load_layer(path: str | Path, name: str) -> np.ndarray:
    try:
        with open(path, "rb") as file:
            head = file.read(len(NPY_MAGIC))
    except FileNotFoundError as err:
        raise TerrainError(f"{name} layer file {str(path)!r} not found", key=name) from err
    except OSError as err:
        raise TerrainError(
            f"{name} layer file {str(path)!r} cannot be read: {err.strerror or err}", key=name
        ) from err
    # np.load takes anything without the magic for a pickle and says so, which misleads.
    if head != NPY_MAGIC:
        raise TerrainError(
            f"{name} layer file {str(path)!r} is not a .npy array "
            f"(it starts with {head!r}, not {NPY_MAGIC!r})",
            key=name,
        )
    try:
        # Mapped first: the header's shape is checked before the data is read into memory.
        mapped = np.load(path, mmap_mode="r", allow_pickle=False)
        if isinstance(mapped, np.ndarray) and mapped.ndim == 2:
            rows, cols = mapped.shape
            check_map_cells(rows, cols, f"{name} layer file {str(path)!r}", "downsample the layers", key=name)
        layer = np.array(mapped)
    except (OSError, ValueError) as err:
        raise TerrainError(
            f"{name} layer file {str(path)!r} is not a readable .npy array: {err}", key=name
        ) from err
    if not isinstance(layer, np.ndarray):
        raise TerrainError(f"{name} layer file {str(path)!r} must hold one 2-D array", key=name)
    # Checked here, not left to TerrainMap, so the error names the layer's key and its file.
    return checked_layer(layer, Layer.file(name, path))


def load_npy_layers(
    elevation: str | Path | None = None,
    classes: str | Path | None = None,
    obstacles: str | Path | None = None,
    *,
    resolution_m: float,
    origin: tuple[float, float] = (0.0, 0.0),
    base_class: int = 0,
) -> TerrainMap:
    """A map from ``.npy`` layers; a missing layer is flat / ``base_class`` / obstacle-free."""
    paths = {"elevation": elevation, "classes": classes, "obstacles": obstacles}
    loaded = {name: _load_layer(path, name) for name, path in paths.items() if path is not None}
    if not loaded:
        raise TerrainError("load_npy_layers needs at least one layer file to know the map's shape")
    check_one_grid([(Layer.file(name, str(paths[name])), layer.shape) for name, layer in loaded.items()])
    shape = next(iter(loaded.values())).shape
    return TerrainMap(
        elevation_m=loaded.get("elevation", np.zeros(shape)),
        terrain_class=loaded.get("classes", np.full(shape, base_class, dtype=np.int64)),
        obstacles=loaded.get("obstacles", np.zeros(shape, dtype=bool)),
        resolution_m=resolution_m,
        origin_xy=origin,
    )


def procedural(
    shape: tuple[int, int],
    resolution_m: float,
    rng: np.random.Generator,
    base_class: int = 0,
    hill_height_m: float = 0.5,
    hill_count: int = 4,
    class_patch_count: int = 0,
    *,
    patch_classes: Sequence[int] | None = None,
    hill_radius_m: tuple[float, float] = (2.0, 6.0),
    patch_radius_m: tuple[float, float] = (1.0, 3.0),
    origin_xy: tuple[float, float] = (0.0, 0.0),
) -> TerrainMap:
    """Seeded smooth hills (a sum of Gaussian bumps) on ``base_class`` ground with disc patches of others.

    Each hill: centre uniform on the map, sigma uniform in ``hill_radius_m``, height uniform in
    ``[0.5, 1] x hill_height_m``. Each patch: a disc of radius uniform in ``patch_radius_m`` of a class
    drawn from ``patch_classes`` (default: every class but the base). Same rng state => same map.
    """
    rows, cols = shape
    if rows < 1 or cols < 1:
        raise TerrainError(f"procedural terrain shape must be at least 1 x 1, got {shape}")
    check_map_cells(rows, cols, "procedural terrain", "ask for fewer rows or columns")
    if hill_count < 0 or class_patch_count < 0 or hill_height_m < 0.0:
        raise TerrainError("procedural hill_count, class_patch_count and hill_height_m must be >= 0")
    if base_class not in TERRAIN_CLASSES:
        raise TerrainError(f"unknown base terrain class {base_class}; known ids: {sorted(TERRAIN_CLASSES)}")
    ox, oy = origin_xy
    xs = ox + (np.arange(cols) + 0.5) * resolution_m
    ys = oy + (np.arange(rows) + 0.5) * resolution_m
    grid_x, grid_y = np.meshgrid(xs, ys)
    width, height = cols * resolution_m, rows * resolution_m

    elevation = np.zeros(shape)
    for _ in range(hill_count):
        cx, cy = ox + rng.uniform(0.0, width), oy + rng.uniform(0.0, height)
        sigma = rng.uniform(*hill_radius_m)
        peak = rng.uniform(0.5, 1.0) * hill_height_m
        elevation += peak * np.exp(-((grid_x - cx) ** 2 + (grid_y - cy) ** 2) / (2.0 * sigma**2))

    classes = np.full(shape, base_class, dtype=np.int64)
    choices = [c for c in (patch_classes or TERRAIN_CLASSES) if c != base_class]
    for _ in range(class_patch_count if choices else 0):
        cx, cy = ox + rng.uniform(0.0, width), oy + rng.uniform(0.0, height)
        radius = rng.uniform(*patch_radius_m)
        patch_class = choices[int(rng.integers(len(choices)))]
        classes[(grid_x - cx) ** 2 + (grid_y - cy) ** 2 <= radius**2] = patch_class

    return TerrainMap(elevation, classes, np.zeros(shape, dtype=bool), resolution_m, origin_xy)


def disc_mask(terrain: TerrainMap, x: float, y: float, radius: float) -> np.ndarray:
    """Cells whose centre lies within ``radius`` of (x, y); at least the cell holding (x, y) if on the map."""
    rows, cols = terrain.shape
    xs = terrain.origin_xy[0] + (np.arange(cols) + 0.5) * terrain.resolution_m
    ys = terrain.origin_xy[1] + (np.arange(rows) + 0.5) * terrain.resolution_m
    dx2, dy2, r2 = (xs - x) ** 2, (ys - y) ** 2, radius**2
    mask = np.zeros((rows, cols), dtype=bool)
    # Only the rows and columns within the radius can hold a cell of the disc (dx2 + dy2 <= r2 needs
    # dy2 <= r2 and dx2 <= r2, rounding too, as both are >= 0): one disc is a small block of a large map.
    in_rows, in_cols = np.flatnonzero(dy2 <= r2), np.flatnonzero(dx2 <= r2)
    if in_rows.size and in_cols.size:
        row0, row1, col0, col1 = in_rows[0], in_rows[-1] + 1, in_cols[0], in_cols[-1] + 1
        mask[row0:row1, col0:col1] = dx2[np.newaxis, col0:col1] + dy2[row0:row1, np.newaxis] <= r2
    if terrain.contains(x, y):
        mask[terrain.cell_of(x, y)] = True
    return mask
