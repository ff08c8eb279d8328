"""Plan repair for one goal on a map whose costs only rise: A* guided by an earlier map's exact cost-to-go.

Once per goal, a backward Dijkstra from the goal (``navigator.cost_to_go_kernel``) gives ``field[c]``, the
exact cost from every cell ``c`` to the goal on the map of that moment. When obstacles are added later,
every edge costs the same or more (cell costs only rise, ``inf`` forbids), so the old field is still

* admissible: a lower bound of the new cost to go, and
* consistent: ``field[a] <= old_edge(a, b) + field[b] <= new_edge(a, b) + field[b]``,

and A* with it as the heuristic returns an optimal path on the new map. Where nothing changed the field is
exact, so A* walks straight down the new path and spends its expansions only around the detour: a repair
after a local change costs a small fraction of a fresh plan, from *any* start (the rover keeps moving).

If costs ever fall (an obstacle removed, a new map), the field is no longer a lower bound: it is dropped
and rebuilt from the new map before the next plan (``update_costs`` checks, in one compiled pass).

A repair's own work is what it expands: its search (``navigator.astar_repair_kernel``) keeps its work
arrays from plan to plan and tells stale cells by a per-cell stamp, so no O(cells) set-up per plan.
"""

from __future__ import annotations

import logging
import math
import operator
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from navigator import astar_bucket_kernel, astar_repair_kernel
from navigator.astar import SQRT2, PlanResult, check_cost_grid, check_factors, trace
from navigator.astar_python import check_cell
from navigator.cost_to_go_kernel import cost_to_go, cost_to_go_buckets
from navigator.errors import NoPathError, PlanningError

_log = logging.getLogger(__name__)

_NO_FACTORS = np.ones((8, 1))


def cost_to_go_field(
    cost: np.ndarray, goal: tuple[int, int], factors: np.ndarray | None = None
) -> np.ndarray:
    """``(rows, cols)`` exact cost from each cell to ``goal`` (``inf`` where the goal cannot be reached)."""
    grid = check_cost_grid(cost)
    rows, cols = grid.shape
    row, col = int(goal[0]), int(goal[1])
    if not (0 <= row < rows and 0 <= col < cols):
        raise PlanningError(f"goal cell {goal} is outside the {rows} x {cols} cost grid")
    flat_factors = _NO_FACTORS if factors is None else check_factors(factors, grid.shape)
    frame, _, c_min, c_max = astar_bucket_kernel.padded(grid.ravel(), cols)
    max_factor = float(np.max(flat_factors, initial=1.0, where=np.isfinite(flat_factors)))
    if math.isfinite(c_min):
        slots = astar_bucket_kernel.slots_needed(SQRT2 * c_max * max_factor, c_min, 0.0, SQRT2)
        if slots <= astar_bucket_kernel.MAX_SLOTS:
            field = cost_to_go_buckets(
                frame, cols, row * cols + col, c_min, slots, flat_factors, factors is not None, SQRT2
            )
            return field.reshape(rows, cols)
    field = cost_to_go(grid.ravel(), cols, row * cols + col, flat_factors, factors is not None, SQRT2)
    return field.reshape(rows, cols)


@dataclass
class RepairStats:
    """What the repairing planner did: fields built, plans made with a field, costs seen to fall."""

    fields_built: int = 0
    plans: int = 0
    fields_dropped: int = 0


class RepairingPlanner:
    """Plans to a goal again and again as costs rise, reusing the goal's cost-to-go field as the heuristic.

    ``cost`` and ``factors`` as for ``navigator.astar.astar``; ``weight`` > 1 inflates the field (the
    cost is then at most ``weight`` times the optimum).
    """

    def __init__(self, cost: np.ndarray, factors: np.ndarray | None = None, weight: float = 1.0) -> None:
        if not (math.isfinite(weight) and weight >= 0.0):
            raise PlanningError(f"heuristic weight must be a finite number >= 0, got {weight}")
        self._cost = check_cost_grid(cost).copy()
        self._factors = None if factors is None else self._checked_factors(factors)
        self._weight = weight
        self._goal: tuple[int, int] | None = None
        self._field: np.ndarray | None = None
        cells = self._cost.size
        self._g = np.empty(cells)
        self._parent = np.empty(cells, dtype=np.int32)
        self._stamp = np.zeros(cells, dtype=np.int32)
        self._plan_id = 0
        self.stats = RepairStats()

    def _checked_factors(self, factors: np.ndarray) -> np.ndarray:
        """A validated ``(8, rows, cols)`` copy (``check_factors`` gives the flat ``(8, cells)`` form)."""
        return check_factors(factors, self._cost.shape).reshape(8, *self._cost.shape).copy()

    @property
    def has_field(self) -> bool:
        return self._field is not None

    def prepare(self, goal: tuple[int, int]) -> None:
        """Build the cost-to-go field of ``goal`` now (otherwise the first ``plan`` to it does)."""
        goal = (int(goal[0]), int(goal[1]))
        if self._field is not None and self._goal == goal:
            return
        self._field = cost_to_go_field(self._cost, goal, self._factors).ravel()
        self._goal = goal
        self.stats.fields_built += 1

    def update_costs(
        self,
        cost: np.ndarray,
        factors: np.ndarray | None = None,
        *,
        windows: Sequence[tuple[int, int, int, int]] | None = None,
    ) -> bool:
        """Take the new costs (and factors, if they changed); returns whether the field is kept.

        It is kept only when no cell cost and no factor fell; otherwise it is dropped (rebuilt lazily).
        ``windows`` (``(row0, row1, col0, col1)`` each, as ``navigator.costs.Window``): where ``cost`` may
        differ from the costs taken before, as ``CostModel.update_grid`` reports them; only those cells are
        checked and copied. None: anywhere (the whole grid is checked and copied: ~2.5 ms a million cells,
        most of a repair after a local change on a large map).
        """
        new_cost = np.asarray(cost)
        if new_cost.shape != self._cost.shape:
            raise PlanningError(
                f"new cost grid has shape {new_cost.shape}, the planner's is {self._cost.shape}; "
                "make a new RepairingPlanner for another map"
            )
        regions = [(slice(None), slice(None))] if windows is None else self._regions(windows)
        # Every region checked before any is taken: a refused grid leaves the planner's costs as they were.
        fresh = [np.ascontiguousarray(new_cost[rows, cols], dtype=np.float64) for rows, cols in regions]
        rose_only = True
        for (rows, cols), region in zip(regions, fresh, strict=True):
            held = np.ascontiguousarray(self._cost[rows, cols])
            bad, rose_here = astar_repair_kernel.costs_rose_only(region.ravel(), held.ravel())
            if bad:
                raise PlanningError(
                    "cost grid must hold costs > 0 or inf (lethal); found NaN or a value <= 0"
                )
            rose_only = rose_only and rose_here
        for (rows, cols), region in zip(regions, fresh, strict=True):
            self._cost[rows, cols] = region
        new_factors = self._factors
        if factors is not None:
            new_factors = self._checked_factors(factors)
            rose_only = rose_only and self._factors is not None and bool(np.all(new_factors >= self._factors))
        self._factors = new_factors
        if not rose_only and self._field is not None:
            _log.info("costs fell somewhere: the cost-to-go field is rebuilt before the next plan")
            self._field = None
            self.stats.fields_dropped += 1
        return self._field is not None

    def _regions(self, windows: Sequence[tuple[int, int, int, int]]) -> list[tuple[slice, slice]]:
        """Each window as slices, refused unless it lies on the grid (a slice would cut it silently)."""
        rows, cols = self._cost.shape
        regions = []
        for window in windows:
            try:
                # Whole numbers only: int() would cut 2.5 to 2 as silently as a slice cuts a window.
                row0, row1, col0, col1 = (operator.index(edge) for edge in window)
            except (TypeError, ValueError) as err:
                raise PlanningError(
                    f"cost window {window!r} must be four whole numbers (row0, row1, col0, col1): {err}"
                ) from err
            if not (0 <= row0 <= row1 <= rows and 0 <= col0 <= col1 <= cols):
                raise PlanningError(
                    f"cost window {tuple(window)} (row0, row1, col0, col1) is not on the {rows} x {cols} grid"
                )
            regions.append((slice(row0, row1), slice(col0, col1)))
        return regions

    def plan(self, start: tuple[int, int], goal: tuple[int, int]) -> PlanResult:
        """Optimal path (``weight`` 1) from ``start`` to ``goal`` on the current costs."""
        start = (int(start[0]), int(start[1]))
        goal = (int(goal[0]), int(goal[1]))
        check_cell(self._cost, start, "start")
        check_cell(self._cost, goal, "goal")
        self.prepare(goal)
        assert self._field is not None
        self.stats.plans += 1
        if self._plan_id == np.iinfo(np.int32).max:  # stamps would repeat: start the count afresh
            self._stamp[:] = 0
            self._plan_id = 0
        self._plan_id += 1
        cols = self._cost.shape[1]
        goal_index = goal[0] * cols + goal[1]
        goal_cost, expanded = astar_repair_kernel.search(
            self._cost.ravel(), cols, start[0] * cols + start[1], goal_index, self._field, self._weight,
            _NO_FACTORS if self._factors is None else self._factors.reshape(8, -1),
            self._factors is not None, SQRT2,
            self._g, self._parent, self._stamp, self._plan_id,
        )  # fmt: skip
        if not math.isfinite(goal_cost):
            raise NoPathError(
                f"no traversable path from cell {start} to cell {goal} ({expanded} cells reachable from "
                "the start); the goal is walled off by obstacles or lethal slopes"
            )
        return PlanResult(trace(self._parent, goal_index, cols), float(goal_cost), int(expanded))
