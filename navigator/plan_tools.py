"""What ``rover plan`` does: load a map, plan once, export the exact edge-cost model, draw the path.

The export (``.npz``) holds everything an independent shortest-path solver needs to check optimality:
``cost`` (rows, cols; inf = lethal), ``factors`` (8, rows, cols; all ones in classical mode), ``moves``
(8, 2) the (d_row, d_col) of each move, ``start``/``goal`` cells, ``path`` cells, ``path_cost`` (the sum of
edge costs in cell units) and ``edge_model``, the formula as text. See docs/planning.md.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path as FilePath

import numpy as np

from logs.settings import Table, load_toml
from navigator.astar import SQRT2, astar
from navigator.astar_kernel import MOVES
from navigator.errors import TerrainError
from navigator.map_config import terrain_from_table
from navigator.planner import Planner
from navigator.png_layers import load_png_layers
from navigator.terrain import TerrainMap, load_npy_layers

Point = tuple[float, float]  # x, y in local ENU metres

EDGE_MODEL = (
    "edge(a -> b by move m) = step(m) * (cost[a] + cost[b]) / 2 * factors[m, a]; step = 1 orthogonal, "
    f"{SQRT2!r} diagonal; a diagonal move needs both orthogonal neighbours finite; inf = not allowed"
)


@dataclass(frozen=True)
class PlanReport:
    cost: float  # cost-weighted metres (A* cost times the resolution)
    length_m: float
    expanded: int
    time_ms: float
    points: np.ndarray
    cells: list[tuple[int, int]]


@dataclass(frozen=True)
class PlanMap:
    """What ``rover plan`` plans on, from one read of its map file: the terrain, and the start (``[start]
    xy``) and first goal (``[[goals]] xy``) the file names, each ``None`` where it names none."""

    terrain: TerrainMap
    start: Point | None = None
    goal: Point | None = None


def load_map(path: FilePath, resolution_m: float | None) -> PlanMap:
    """A TOML file with a ``[terrain]`` table (a scenario qualifies), an ``.npy`` elevation layer, or a
    ``.png`` obstacle image (dark = obstacle, image top = north; the form a drawn maze takes)."""
    suffix = path.suffix.lower()
    if suffix in (".npy", ".png"):
        if resolution_m is None:
            raise TerrainError(f"a {suffix} map needs its resolution (--resolution-m)")
        if suffix == ".png":
            return PlanMap(load_png_layers(obstacles=path, resolution_m=resolution_m))
        return PlanMap(load_npy_layers(elevation=path, resolution_m=resolution_m))
    if resolution_m is not None:
        # A TOML map sets its own cell size; ignoring the option would plan at a resolution not asked for.
        raise TerrainError(f"--resolution-m is for a .npy / .png map; {path} sets resolution_m in [terrain]")
    return map_from_table(load_toml(path), path.parent)


def map_from_table(root: Table, base_dir: FilePath) -> PlanMap:
    """The ``[terrain]`` of a parsed TOML file (layer files read relative to ``base_dir``) and the
    endpoints it names; a malformed one is a ``ConfigError`` naming the key."""
    terrain, _ = terrain_from_table(root.table("terrain"), base_dir)
    start_table = root.table("start", optional=True)
    start = start_table.point("xy") if start_table.has("xy") else None
    goals = root.tables("goals")
    goal = goals[0].point("xy") if goals and goals[0].has("xy") else None
    return PlanMap(terrain, start, goal)


def plan_once(planner: Planner, start_xy: Point, goal_xy: Point) -> PlanReport:
    """One ``Planner.plan``, as the rover plans: a start in an obstacle's clearance band escapes to the
    nearest free cell, and the footprint post-check may replan; ``cells`` are the cells of that path."""
    for search in ("bucket", "heap"):  # load both compiled kernels before the stopwatch starts
        astar(np.ones((2, 2)), (0, 0), (1, 1), search=search)
    began = time.perf_counter()  # the CLI's stopwatch: this is a user-facing timing, not a component clock
    path = planner.plan(start_xy, goal_xy)
    elapsed = (time.perf_counter() - began) * 1e3
    return PlanReport(path.cost, path.length_m, path.expanded, elapsed, path.points, list(path.cells))


def export_costs(planner: Planner, report: PlanReport, out: FilePath) -> None:
    factors = planner.direction_factors
    cost = planner.cost_grid
    np.savez_compressed(
        out,
        cost=np.asarray(cost),
        factors=np.ones((8, *cost.shape)) if factors is None else np.asarray(factors),
        moves=MOVES,
        start=np.array(report.cells[0]),
        goal=np.array(report.cells[-1]),
        path=np.array(report.cells),
        path_cost=np.array(report.cost / planner.terrain.resolution_m),
        resolution_m=np.array(planner.terrain.resolution_m),
        edge_model=np.array(EDGE_MODEL),
    )


def draw_png(planner: Planner, report: PlanReport, out: FilePath) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    terrain = planner.terrain
    width, height = terrain.size_m
    ox, oy = terrain.origin_xy
    extent = (ox, ox + width, oy, oy + height)
    figure, axes = plt.subplots(figsize=(8, 8 * height / max(width, 1e-9) + 0.5))
    shown = np.where(np.isfinite(planner.cost_grid), planner.cost_grid, np.nan)
    image = axes.imshow(shown, origin="lower", extent=extent, cmap="viridis")
    lethal = np.ma.masked_where(np.isfinite(planner.cost_grid), np.ones(terrain.shape))
    axes.imshow(lethal, origin="lower", extent=extent, cmap="Greys", vmin=0, vmax=1.5, alpha=0.9)
    if np.ptp(terrain.elevation_m) > 0:
        axes.contour(terrain.elevation_m, origin="lower", extent=extent, colors="white", linewidths=0.4)
    axes.plot(report.points[:, 0], report.points[:, 1], color="red", linewidth=1.5)
    axes.plot(*report.points[0], "o", color="white")
    axes.plot(*report.points[-1], "*", color="white", markersize=12)
    axes.set_xlabel("east (m)")
    axes.set_ylabel("north (m)")
    axes.set_title(f"{planner.cost_mode} cost: {report.cost:.1f}, {report.length_m:.1f} m")
    figure.colorbar(image, ax=axes, label="cell cost (grey: lethal)")
    figure.savefig(out, format="png", dpi=120, bbox_inches="tight")  # --png is PNG whatever its name ends in
    plt.close(figure)
