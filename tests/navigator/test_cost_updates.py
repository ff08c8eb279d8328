"""Obstacle updates of the cost grid: recomputed only in the windows the changed cells reach, and equal,
bit for bit, to the grid made anew (``CostModel.update_grid``, ``Planner.update_obstacles`` and
``reset_obstacles``)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from navigator.costs import CostModel, _ObstacleTerms, change_windows
from navigator.errors import ParameterError
from navigator.planner import Planner
from navigator.terrain import TerrainMap, disc_mask
from navigator.vehicle import VehicleParams

PARAMS = VehicleParams()


def _terrain(rows: int, cols: int, res: float, seed: int) -> TerrainMap:
    rng = np.random.default_rng(seed)
    elevation = rng.normal(0.0, 0.04, (rows, cols))
    classes = rng.integers(0, 3, (rows, cols)).astype(np.uint8)
    obstacles = rng.random((rows, cols)) < 0.01
    return TerrainMap(elevation, classes, obstacles, res)


# One change: rectangles of obstacle cells added (True) or taken off (False), (row, col, height, width).
rectangles = st.lists(
    st.tuples(st.integers(0, 47), st.integers(0, 47), st.integers(1, 4), st.integers(1, 4)), max_size=6
)
changes = st.lists(st.tuples(st.booleans(), rectangles), min_size=1, max_size=5)


def _apply(obstacles: np.ndarray, add: bool, boxes: list[tuple[int, int, int, int]]) -> np.ndarray:
    changed = obstacles.copy()
    for row, col, height, width in boxes:
        changed[row : row + height, col : col + width] = add
    return changed


@settings(max_examples=60, deadline=None)
@given(
    shape=st.tuples(st.integers(1, 48), st.integers(1, 48)),
    res=st.sampled_from([0.1, 0.25, 0.5]),
    inflation_m=st.sampled_from([0.0, 0.1, 0.37]),
    band_m=st.sampled_from([0.0, 0.6, 1.0, 2.5]),
    weight=st.sampled_from([0.0, 4.0]),
    edge=st.booleans(),
    seed=st.integers(0, 2**16),
    steps=changes,
)
def test_updated_grid_equals_the_grid_made_anew(
    shape: tuple[int, int],
    res: float,
    inflation_m: float,
    band_m: float,
    weight: float,
    edge: bool,
    seed: int,
    steps: list[tuple[bool, list[tuple[int, int, int, int]]]],
) -> None:
    base = _terrain(*shape, res, seed)
    model = CostModel(
        inflation_m=inflation_m, proximity_band_m=band_m, proximity_weight=weight, edge_is_obstacle=edge
    )
    ground = model.ground_cost(base, PARAMS)
    terrain = base
    cost = model.grid(terrain, PARAMS, ground=ground)
    for add, boxes in steps:
        before, before_cost = terrain.obstacles, cost.copy()
        # Obstacles added and taken off, as a planner's map after ``with_obstacles`` or a reset.
        terrain = TerrainMap(base.elevation_m, base.terrain_class, _apply(before, add, boxes), res)
        ground = model.ground_cost(terrain, PARAMS)  # the new map's own layers (equal values)
        change = model.update_grid(cost, terrain, PARAMS, ground, before)
        fresh = model.grid(terrain, PARAMS)
        np.testing.assert_array_equal(cost, fresh)  # bit for bit, inf where lethal
        np.testing.assert_array_equal(change.changed, before_cost != fresh)
        outside = np.ones(shape, dtype=bool)  # the windows hold every change
        for row0, row1, col0, col1 in change.windows:
            outside[row0:row1, col0:col1] = False
        assert not (before_cost != fresh)[outside].any()


@settings(max_examples=25, deadline=None)
@given(
    cost_mode=st.sampled_from(["terrain", "classical"]),
    footprint_inflation=st.sampled_from(["circumscribed", "inscribed"]),
    seed=st.integers(0, 2**16),
    discs=st.lists(
        st.tuples(st.floats(0.0, 12.0), st.floats(0.0, 9.0), st.floats(0.0, 1.5), st.booleans()),
        min_size=1,
        max_size=8,
    ),
)
def test_planner_updates_equal_a_planner_made_on_the_new_map(
    cost_mode: str,
    footprint_inflation: str,
    seed: int,
    discs: list[tuple[float, float, float, bool]],
) -> None:
    """Random discs added (``update_obstacles``) or the map reset to the given one plus the discs still
    standing (``reset_obstacles``, some taken off): the planner's grid is that of a planner made anew."""
    base = _terrain(36, 48, 0.25, seed)
    planner = Planner(base, PARAMS, cost_mode=cost_mode, footprint_inflation=footprint_inflation)
    standing = np.zeros(base.shape, dtype=bool)
    for x, y, radius, keep_others in discs:
        disc = disc_mask(base, x, y, radius)
        if keep_others:
            standing |= disc
            before = planner.cost_grid.copy()
            changed = planner.update_obstacles(disc)
        else:  # the ones before this one moved on: only this one stands now
            standing = disc
            before = planner.cost_grid.copy()
            changed = planner.reset_obstacles(disc)
        fresh = Planner(
            base.with_obstacles(standing),
            PARAMS,
            cost_mode=cost_mode,
            footprint_inflation=footprint_inflation,
        )
        np.testing.assert_array_equal(planner.cost_grid, fresh.cost_grid)
        np.testing.assert_array_equal(changed, before != fresh.cost_grid)
    assert planner.grid_updates == len(discs)


def test_one_changed_cell_recomputes_one_window_of_its_reach() -> None:
    """What makes the update incremental: a rock on a large map is one window of (2 reach + 1)^2 cells."""
    terrain = _terrain(400, 400, 0.25, 1)
    model = CostModel()
    reach = model._terms(PARAMS).reach_cells(0.25)
    changed = np.zeros(terrain.shape, dtype=bool)
    changed[200, 50] = True
    assert change_windows(changed, reach) == [(200 - reach, 201 + reach, 50 - reach, 51 + reach)]
    changed[0, 399] = True  # far away: a window of its own, cut to the map
    changed[203, 52] = True  # near the first: the same window
    assert sorted(change_windows(changed, reach)) == [
        (0, reach + 1, 399 - reach, 400),
        (200 - reach, 204 + reach, 50 - reach, 53 + reach),
    ]
    assert change_windows(np.zeros((5, 5), dtype=bool), reach) == []


def test_the_reach_covers_inflation_and_the_clearance_band() -> None:
    # 0.67 m of clearance + a 1 m band at 0.25 m: the term is zero past 1.67 m = 6.7 cells; + 1 of margin.
    terms = _ObstacleTerms(clearance_m=0.67, weight=4.0, band_m=1.0, edge_is_obstacle=True)
    assert terms.proximity_reach(0.25) == 8 and terms.reach_cells(0.25) == 8
    no_band = _ObstacleTerms(clearance_m=0.67, weight=4.0, band_m=0.0, edge_is_obstacle=True)
    assert no_band.proximity_reach(0.25) == 0 and no_band.reach_cells(0.25) == 4  # ceil(0.67 / 0.25 + 0.5)


def test_update_grid_refuses_another_maps_ground_or_shape() -> None:
    terrain = _terrain(10, 10, 0.25, 2)
    model = CostModel()
    cost = model.grid(terrain, PARAMS)
    other = _terrain(10, 10, 0.25, 3)
    with pytest.raises(ParameterError, match="made for another terrain"):
        model.update_grid(cost, terrain, PARAMS, model.ground_cost(other, PARAMS), terrain.obstacles)
    with pytest.raises(ParameterError, match="must have the map's shape"):
        model.update_grid(cost[:5], terrain, PARAMS, model.ground_cost(terrain, PARAMS), terrain.obstacles)


def test_the_benchmark_row_times_equal_grids() -> None:
    from navigator.plan_bench import obstacle_update_figures

    figures = obstacle_update_figures(96, seed=4, repeats=1)
    assert figures["same_grid"] and figures["size"] == 96
    assert figures["update_ms"] > 0.0 and figures["full_ms"] > 0.0


@pytest.mark.parametrize("cost_mode", ["terrain", "classical"])
def test_a_repairing_planner_takes_each_update_in_its_windows(cost_mode: str) -> None:
    """``reuse_goal_field``: the repair sees only the windows the grid update recomputed; its plans after
    rocks added and taken off cost what a planner made anew on that map plans."""
    rough = _terrain(60, 80, 0.25, 4)
    base = TerrainMap(rough.elevation_m, rough.terrain_class, np.zeros(rough.shape, dtype=bool), 0.25)
    start, goal = (15, 15), (45, 65)  # (3.75, 3.75) m and (16.25, 11.25) m: the rocks lie between
    planner = Planner(base, PARAMS, cost_mode=cost_mode, reuse_goal_field=True)
    planner.plan_cells(start, goal)
    first = disc_mask(base, 10.0, 7.5, 0.8)
    second = disc_mask(base, 7.0, 5.7, 0.6)
    for update, standing in (
        (lambda: planner.update_obstacles(first), first),
        (lambda: planner.update_obstacles(second), first | second),
        (lambda: planner.reset_obstacles(second), second),  # the first moved on: a cost fell
    ):
        update()
        fresh = Planner(base.with_obstacles(standing), PARAMS, cost_mode=cost_mode)
        assert planner.plan_cells(start, goal).cost == pytest.approx(
            fresh.plan_cells(start, goal).cost, rel=1e-12
        )
