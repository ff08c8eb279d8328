"""World-frame planning: ENU points -> map cells -> A* over the traversability grid -> ENU waypoints.

Two cost modes (``COST_MODES``):

* ``"terrain"`` (default): the full model, per-cell costs of ``navigator.costs`` (class, slope, roughness,
  obstacle clearance) times the direction factors of ``navigator.direction_costs`` (climb, descent, side
  slope, and moves past the tip-over / climb limits forbidden);
* ``"classical"``: the paper's baseline, obstacles only: cost 1 everywhere but the inflated obstacles
  (lethal) and the same soft clearance band; no terrain class, slope or direction costs.

Footprint: the cost grid inflates obstacles by a circle (``footprint_inflation``): the ``circumscribed``
circle (default; pessimistic: it never lets the rectangle touch at a cell centre but blocks squeezing
lengthwise through a gap narrower than the rover's diagonal) or the ``inscribed`` one (optimistic: it
lets A* through such gaps but misses the corners). Either way ``plan`` then walks the path with the
oriented rectangle (``navigator.footprint.first_collision``, heading along the path, turns on the spot at
corners); where it hits, the move (cell to cell) of the path segment it hit on is forbidden and A* runs again
(from the same start, same costs, those moves forbidden), up to ``MAX_FOOTPRINT_RETRIES`` times, then
NoPathError. With the circumscribed circle a hit is rare (the rectangle is inside the circle at every
cell centre; the exact goal point off its cell centre can touch), so the check costs one walk of the
path; with the inscribed one, squeezes and turns in tight places can cost several A* runs.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from navigator.astar import HEURISTICS, PlanResult, astar
from navigator.astar_kernel import MOVES
from navigator.costs import CostModel, GroundCost
from navigator.direction_costs import DirectionWeights, direction_factors
from navigator.errors import NoPathError, PlanningError, TerrainError
from navigator.footprint import Collision, Footprint, first_collision
from navigator.replanning import RepairingPlanner
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TERRAIN_CLASSES, TerrainClass
from navigator.vehicle import VehicleParams, max_climbable_slope_rad

if TYPE_CHECKING:  # navigator.config imports this module for its choices
    from navigator.config import PlannerConfig

_log = logging.getLogger(__name__)

ESCAPE_RADIUS_M = 1.5
# A start lethal by its slope alone, with nothing passable within ``ESCAPE_RADIUS_M``, plans from the nearest
# passable cell within this: the rover stands on a slope its beliefs now forbid (it learned, on that slope,
# that the class grips less: navigator.slide_learning) and the way off it is the plan's first leg, checked
# for the footprint from where the rover is (a side-slope band, a dune's flank: a few metres across).
SLOPE_ESCAPE_RADIUS_M = 5.0
COST_MODES = ("terrain", "classical")
FOOTPRINT_INFLATIONS = ("circumscribed", "inscribed")
MAX_FOOTPRINT_RETRIES = 40
MOVE_INDEX = {(int(d_row), int(d_col)): index for index, (d_row, d_col) in enumerate(MOVES)}


@dataclass(frozen=True)
class Path:
    """A planned path in local ENU.

    ``points``: ``(n, 2)`` metres, first the start position, last the goal position, cell centres between;
    read-only when the planner made it.
    ``cost``: the A* cost times the map resolution (cost-weighted metres). ``length_m``: polyline length.
    ``checked_from_m``: the oriented footprint is clear of obstacles from this distance along the path on;
    before it the rover gets from where it is to the search's first cell centre (its start is a fact).
    ``cells``: the searched ``(row, col)`` cells, from the (escaped) start cell to the goal cell.
    """

    points: np.ndarray
    cost: float
    length_m: float
    expanded: int
    checked_from_m: float = 0.0
    cells: tuple[tuple[int, int], ...] = ()


class Planner:
    """Plans over one terrain map with the vehicle parameters the navigator believes; caches the cost grid."""

    def __init__(
        self,
        terrain: TerrainMap,
        params: VehicleParams,
        *,
        heuristic: str = "octile",
        inflation_m: float = 0.1,
        classes: dict[int, TerrainClass] = TERRAIN_CLASSES,
        cost_model: CostModel | None = None,
        cost_mode: str = "terrain",
        direction_weights: DirectionWeights | None = None,
        heuristic_weight: float = 1.0,
        reuse_goal_field: bool = False,
        footprint_inflation: str = "circumscribed",
    ) -> None:
        """``footprint_inflation``: the circle the cost grid inflates obstacles by (module docstring).

        ``reuse_goal_field``: plan with ``navigator.replanning`` (the goal's cost-to-go field as the
        heuristic, built once per goal and kept while obstacles only add cost): the first plan to a goal
        costs about one full Dijkstra, every later one (new start, new obstacles) a small fraction."""
        if heuristic not in HEURISTICS:
            raise PlanningError(f"unknown heuristic {heuristic!r}; choose one of {', '.join(HEURISTICS)}")
        if cost_mode not in COST_MODES:
            raise PlanningError(f"unknown cost mode {cost_mode!r}; choose one of {', '.join(COST_MODES)}")
        if footprint_inflation not in FOOTPRINT_INFLATIONS:
            raise PlanningError(
                f"unknown footprint inflation {footprint_inflation!r}; choose one of "
                f"{', '.join(FOOTPRINT_INFLATIONS)}"
            )
        self._params = params
        self._footprint = Footprint.of(params)
        self._inflation_params = params
        if footprint_inflation == "inscribed":
            # The cost grid inflates by params.footprint_radius_m (half the rectangle's diagonal); a square
            # of side r * sqrt(2) has the circumscribed radius r, so this hands it the inscribed circle.
            side = self._footprint.inscribed_radius_m * math.sqrt(2.0)
            self._inflation_params = dataclasses.replace(
                params, footprint_length_m=side, footprint_width_m=side
            )
        self._classes = classes
        self._heuristic = heuristic
        self._heuristic_weight = heuristic_weight
        self._cost_mode = cost_mode
        self._direction_weights = direction_weights or DirectionWeights()
        self._cost_model = cost_model or CostModel(inflation_m=inflation_m)
        # Classical mode's flat layers (``_costed``), made once: every obstacle update shares them.
        self._flat = _flattened(terrain) if cost_mode == "classical" else None
        self.grid_updates = 0  # obstacle updates of the cost grid (``_set_terrain``)
        self._terrain = terrain
        self._base_terrain = terrain  # the map as given: obstacles added later can be taken off again
        costed = self._costed(terrain)
        # The grid's obstacle-free part: every map the planner takes later is this one with other obstacles
        # (``TerrainMap.with_obstacles`` shares the elevation and class layers), so it is made once and an
        # obstacle update skips refiltering the whole map (``CostModel.update_grid`` checks the layers).
        self._ground: GroundCost = self._cost_model.ground_cost(costed, self._inflation_params, classes)
        self._cost = self._cost_model.grid(costed, self._inflation_params, classes, ground=self._ground)
        self._factors: np.ndarray | None = None
        if cost_mode == "terrain":
            self._factors = direction_factors(terrain, params, classes, self._direction_weights)
        self._repairing: RepairingPlanner | None = None
        if reuse_goal_field:
            self._repairing = RepairingPlanner(self._cost, self._factors, heuristic_weight)

    @classmethod
    def from_config(
        cls,
        terrain: TerrainMap,
        params: VehicleParams,
        config: PlannerConfig,
        *,
        classes: dict[int, TerrainClass] = TERRAIN_CLASSES,
        reuse_goal_field: bool = False,
    ) -> Planner:
        """The planner a rover config's ``[planner]`` describes: the one way guidance (on the rover, in HIL)
        and ``rover plan --config`` build it, so a setting added to ``PlannerConfig`` reaches both."""
        return cls(
            terrain,
            params,
            heuristic=config.heuristic,
            inflation_m=config.inflation_m,
            classes=classes,
            cost_mode=config.cost_mode,
            heuristic_weight=config.heuristic_weight,
            reuse_goal_field=reuse_goal_field,
            footprint_inflation=config.footprint_inflation,
        )

    @property
    def terrain(self) -> TerrainMap:
        return self._terrain

    @property
    def climb_margin_rad(self) -> float:
        """How far below each class's climb limit the cost grid forbids a slope (``CostModel``)."""
        return self._cost_model.climb_margin_rad

    @property
    def cost_grid(self) -> np.ndarray:
        """The cached ``(rows, cols)`` cost grid (read-only view; obstacle updates change it in place, so
        copy it to keep the costs of one moment)."""
        view = self._cost.view()
        view.setflags(write=False)
        return view

    @property
    def direction_factors(self) -> np.ndarray | None:
        """The ``(8, rows, cols)`` direction factors (None in classical mode), read-only."""
        if self._factors is None:
            return None
        view = self._factors.view()
        view.setflags(write=False)
        return view

    @property
    def cost_mode(self) -> str:
        return self._cost_mode

    def _costed(self, terrain: TerrainMap) -> TerrainMap:
        """The map the cost grid is computed on: ``terrain``, or in classical mode (obstacles only) its
        obstacles on the same map flattened to firm ground, so no slope, roughness or class cost and no
        lethal slope; obstacle inflation and the clearance band stay. The flat layers are shared, so the
        flat map's ground cost is kept as the terrain's is."""
        return terrain if self._flat is None else self._flat.with_obstacles(terrain.obstacles)

    def update_obstacles(self, mask: np.ndarray) -> np.ndarray:
        """Add obstacle cells (bool, map shape) and update the costs; returns where the cost changed."""
        return self._set_terrain(self._terrain.with_obstacles(mask))

    def reset_obstacles(self, mask: np.ndarray) -> np.ndarray:
        """The map as given plus exactly ``mask`` (bool, map shape): obstacles added before and not in it
        are taken off (an obstacle seen standing that has since moved on). Returns where the cost changed;
        costs that fell drop the repair's cost-to-go field (rebuilt before the next plan)."""
        return self._set_terrain(self._base_terrain.with_obstacles(mask))

    def _set_terrain(self, terrain: TerrainMap) -> np.ndarray:
        """Take ``terrain`` (this map's layers, other obstacles) and update the cost grid in place where its
        obstacles differ (``CostModel.update_grid``: the grid made anew, bit for bit, but only the windows
        the changed cells reach are recomputed: on a large map a whole-map dilation and distance transform
        per obstacle seen was most of a replan)."""
        before = self._terrain.obstacles
        self._terrain = terrain
        costed = self._costed(terrain)
        change = self._cost_model.update_grid(
            self._cost, costed, self._inflation_params, self._ground, before
        )
        self.grid_updates += 1
        if self._repairing is not None:
            # Only the recomputed windows: a whole-grid check and copy cost more than the update itself.
            self._repairing.update_costs(self._cost, windows=change.windows)
        return change.changed

    def plan_cells(self, start_cell: tuple[int, int], goal_cell: tuple[int, int]) -> PlanResult:
        """A* between two cells over the current costs (no start escape)."""
        if self._repairing is not None:
            return self._repairing.plan(start_cell, goal_cell)
        return astar(
            self._cost, start_cell, goal_cell, self._heuristic, self._heuristic_weight, self._factors
        )

    def plan(self, start_xy: tuple[float, float], goal_xy: tuple[float, float]) -> Path:
        """Path from ``start_xy`` to ``goal_xy`` (ENU metres); PlanningError / NoPathError when impossible.

        A rover whose estimated position lies in the clearance band around an obstacle (estimation noise,
        or it was pushed there) starts from the nearest free cell within ``ESCAPE_RADIUS_M``: the path then
        leads it out of the band. Inside an obstacle cell itself there is no such escape. A rover on a slope
        too steep for its class's believed grip (and nothing passable within that radius) starts from the
        nearest passable cell within ``SLOPE_ESCAPE_RADIUS_M`` whose straight way from the start crosses
        only passable ground or the start's own class's too-steep slope (``_off_slope``); that way is then
        checked for the footprint against obstacles like the rest of the path.
        """
        asked = self._cell(start_xy, "start")
        start_cell = self._escape(asked, ESCAPE_RADIUS_M)
        off_slope = start_cell == asked and self._slope_lethal(asked)
        if off_slope:
            start_cell = self._off_slope(asked)
        goal_cell = self._cell(goal_xy, "goal")
        result = self.plan_cells(start_cell, goal_cell)
        factors: np.ndarray | None = None  # a copy with the moves found impossible forbidden, once needed
        for attempt in range(MAX_FOOTPRINT_RETRIES + 1):
            path = self._path(result, start_xy, goal_xy)
            # The way from where the rover is to its first cell centre is not checked: the start is a fact.
            # Off a slope, that way is metres long: it is checked (the start pose with it).
            first_centre = self._terrain.center_of(*result.cells[0])
            skip_m = (
                0.0
                if off_slope
                else float(np.hypot(first_centre[0] - start_xy[0], first_centre[1] - start_xy[1]))
            )
            collision = first_collision(path.points, self._terrain, self._footprint, skip_m=skip_m)
            if collision is None:
                return dataclasses.replace(path, checked_from_m=skip_m)
            if attempt == MAX_FOOTPRINT_RETRIES or len(result.cells) < 2:
                break
            if factors is None:
                factors = np.ones((8, *self._cost.shape)) if self._factors is None else self._factors.copy()
            # Segment i of the path is the move cells[i] -> cells[i+1] (the ends are the exact start and
            # goal points inside those cells); the rectangle cannot make it (or the turn onto it), so A*
            # must not use that move out of that cell. Blocking the move, not the cell, keeps one-cell-wide
            # squeezes open: the rover may still pass straight through and turn further on.
            (row, col), (next_row, next_col) = (
                result.cells[collision.index],
                result.cells[collision.index + 1],
            )
            move = MOVE_INDEX[(next_row - row, next_col - col)]
            factors[move, row, col] = np.inf
            _log.debug(
                "footprint hits %s at (%.2f, %.2f); replanning",
                collision.cells.tolist(),
                collision.x,
                collision.y,
            )
            try:
                result = astar(
                    self._cost, start_cell, goal_cell, self._heuristic, self._heuristic_weight, factors
                )
            except PlanningError as err:  # no way is left
                raise NoPathError(f"{self._misfit(collision)} and no other way is left ({err})") from err
        raise NoPathError(f"{self._misfit(collision)} after {MAX_FOOTPRINT_RETRIES} replans")

    def _misfit(self, collision: Collision | None) -> str:
        where = "" if collision is None else f" at ({collision.x:.2f}, {collision.y:.2f})"
        size = f"{self._footprint.length_m} x {self._footprint.width_m} m"
        return f"the rover's {size} footprint does not fit: it hits an obstacle{where}"

    def _path(self, result: PlanResult, start_xy: tuple[float, float], goal_xy: tuple[float, float]) -> Path:
        centres = [self._terrain.center_of(row, col) for row, col in result.cells]
        # The ends are the exact positions asked for, not their cell centres.
        inner = centres[1:-1]
        points = np.array([tuple(map(float, start_xy)), *inner, tuple(map(float, goal_xy))], dtype=np.float64)
        # A plan does not change once made; read-only, the follower knows it again by identity each tick
        # instead of comparing every point (``PurePursuit._adopt``).
        points.flags.writeable = False
        length = float(np.sum(np.hypot(*np.diff(points, axis=0).T)))
        cells = tuple((int(row), int(col)) for row, col in result.cells)
        path = Path(points, result.cost * self._terrain.resolution_m, length, result.expanded, cells=cells)
        _log.debug(
            "planned %d points, %.1f m, cost %.1f, %d cells expanded",
            len(points),
            length,
            path.cost,
            path.expanded,
        )
        return path

    def _slope_lethal(self, cell: tuple[int, int]) -> bool:
        """Lethal by its slope for its class (an obstacle's clearance may reach it too: the way off is
        checked for the footprint)."""
        row, col = cell
        return bool(self._ground.lethal[row, col]) and not self._terrain.obstacles[row, col]

    def _off_slope(self, cell: tuple[int, int]) -> tuple[int, int]:
        """The nearest passable cell within ``SLOPE_ESCAPE_RADIUS_M`` of ``cell`` (lethal by its slope) whose
        straight way from ``cell`` crosses only passable cells or ``cell``'s own class's lethal slope: not
        another class's slope too steep for it (a strip of mud between the sand the rover stands on and the
        firm ground), not an obstacle's clearance; ``cell`` itself when there is none (A* then says so).
        A way that climbs, on the whole, steeper than the class is believed to climb is taken only when no
        other is (down or across the slope first, however much nearer the ground uphill is)."""
        row, col = cell
        reach = int(np.ceil(SLOPE_ESCAPE_RADIUS_M / self._terrain.resolution_m))
        rows = slice(max(0, row - reach), row + reach + 1)
        cols = slice(max(0, col - reach), col + reach + 1)
        free_rows, free_cols = np.nonzero(np.isfinite(self._cost[rows, cols]))
        rr, cc = free_rows + rows.start, free_cols + cols.start
        squared = (rr - row) ** 2 + (cc - col) ** 2
        own_class = self._terrain.terrain_class[row, col]
        # Ground the rover climbs to only when there is no other way: its class's grip is believed too weak
        # for this slope, so a way up it is the way it just failed on (or slid off). A way that climbs no
        # steeper than the class is believed to climb comes first, the nearest of those; then the rest.
        grade = (self._terrain.elevation_m[rr, cc] - self._terrain.elevation_m[row, col]) / (
            np.sqrt(squared) * self._terrain.resolution_m
        )
        climbs = grade > math.tan(self._climb_limit_rad(int(own_class)))
        order = np.lexsort((squared, climbs))
        for index in order:
            target = (int(rr[index]), int(cc[index]))
            if self._way_stays_on(cell, target, own_class):
                _log.info("start cell %s: a slope too steep for its class; starting from %s", cell, target)
                return target
        return cell

    def _climb_limit_rad(self, class_id: int) -> float:
        """The steepest slope ``class_id``'s believed grip climbs, less the cost model's margin: the slope
        past which the planner calls it lethal (``costs.ground_cost``); 0 in classical mode (flat layers)."""
        terrain_class = self._classes.get(class_id)
        if terrain_class is None or self._cost_mode == "classical":
            return 0.0
        return max_climbable_slope_rad(
            terrain_class.friction_mu, terrain_class.rolling_resistance, self._cost_model.climb_margin_rad
        )

    def _way_stays_on(self, start: tuple[int, int], end: tuple[int, int], own_class: int) -> bool:
        """Whether every cell on the straight line from ``start`` to ``end`` (sampled at half a cell) is
        passable or lethal only by its slope with ``own_class``."""
        steps = 2 * max(abs(end[0] - start[0]), abs(end[1] - start[1])) + 1
        for k in range(steps + 1):
            f = k / steps
            r = round(start[0] + f * (end[0] - start[0]))
            c = round(start[1] + f * (end[1] - start[1]))
            if np.isfinite(self._cost[r, c]):
                continue
            if not (self._ground.lethal[r, c] and self._terrain.terrain_class[r, c] == own_class):
                return False
        return True

    def _escape(self, cell: tuple[int, int], radius_m: float) -> tuple[int, int]:
        row, col = cell
        if np.isfinite(self._cost[row, col]) or self._terrain.obstacles[row, col]:
            return cell
        reach = int(np.ceil(radius_m / self._terrain.resolution_m))
        rows = slice(max(0, row - reach), row + reach + 1)
        cols = slice(max(0, col - reach), col + reach + 1)
        window = self._cost[rows, cols]
        free_rows, free_cols = np.nonzero(np.isfinite(window))
        if free_rows.size == 0:
            return cell  # A* reports the lethal start with its own clear error
        rr = free_rows + rows.start
        cc = free_cols + cols.start
        nearest = int(np.argmin((rr - row) ** 2 + (cc - col) ** 2))
        _log.info(
            "start cell %s is inside a clearance band; starting from free cell %s",
            cell,
            (rr[nearest], cc[nearest]),
        )
        return int(rr[nearest]), int(cc[nearest])

    def _cell(self, xy: tuple[float, float], what: str) -> tuple[int, int]:
        try:
            return self._terrain.cell_of(float(xy[0]), float(xy[1]))
        except TerrainError as err:
            raise PlanningError(f"{what} position is not on the map: {err}") from err


def _flattened(terrain: TerrainMap) -> TerrainMap:
    """``terrain``'s grid flattened to firm ground with no obstacles (classical mode's layers)."""
    return TerrainMap(
        np.zeros(terrain.shape), np.zeros(terrain.shape, np.uint8), np.zeros(terrain.shape, bool),
        terrain.resolution_m, terrain.origin_xy,
    )  # fmt: skip
