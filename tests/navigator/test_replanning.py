"""Plan repair with the goal's cost-to-go field: exact field, optimal repairs as costs rise, fall-back."""

import numpy as np
import pytest

from navigator.astar import SQRT2, astar
from navigator.cost_to_go_kernel import cost_to_go
from navigator.errors import NoPathError, PlanningError
from navigator.replanning import RepairingPlanner, cost_to_go_field
from tests.navigator.test_astar import dijkstra_cost


def _random_map(seed: int, shape: tuple[int, int] = (30, 40)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    cost = 1.0 + 4.0 * rng.random(shape)
    cost[rng.random(shape) < 0.2] = np.inf
    cost[0, 0] = cost[-1, -1] = 1.0
    return cost


def _random_factors(seed: int, shape: tuple[int, int]) -> np.ndarray:
    rng = np.random.default_rng(seed)
    factors = 1.0 + rng.random((8, *shape))
    factors[rng.random(factors.shape) < 0.05] = np.inf
    return factors


@pytest.mark.parametrize("seed", [0, 1])
def test_field_is_the_exact_cost_to_go(seed: int) -> None:
    cost = _random_map(seed, (14, 17))
    goal = (13, 16)
    field = cost_to_go_field(cost, goal)
    rng = np.random.default_rng(seed)
    finite = np.argwhere(np.isfinite(cost))
    for row, col in finite[rng.choice(len(finite), 6, replace=False)]:
        assert field[row, col] == pytest.approx(dijkstra_cost(cost, (row, col), goal), rel=1e-12)


def test_field_with_direction_factors_matches_forward_astar() -> None:
    cost = _random_map(3)
    factors = _random_factors(3, cost.shape)
    goal = (29, 39)
    field = cost_to_go_field(cost, goal, factors)
    for start in [(0, 0), (5, 20), (17, 3)]:
        if not np.isfinite(cost[start]):
            continue
        expected = astar(cost, start, goal, factors=factors).cost if np.isfinite(field[start]) else np.inf
        assert field[start] == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("seed", [4, 5, 6])
def test_repairs_as_obstacles_appear_cost_the_same_as_fresh_plans(seed: int) -> None:
    rng = np.random.default_rng(seed)
    cost = _random_map(seed, (60, 60))
    factors = _random_factors(seed, cost.shape)
    goal = (59, 59)
    planner = RepairingPlanner(cost, factors)
    start = (0, 0)
    fresh = astar(cost, start, goal, factors=factors)
    repaired = planner.plan(start, goal)
    assert repaired.cost == pytest.approx(fresh.cost, rel=1e-12)
    for _ in range(4):
        # A block dropped on the current path, the rover a few cells further along it.
        row, col = repaired.cells[len(repaired.cells) // 2]
        cost = cost.copy()
        cost[row - 1 : row + 2, col - 1 : col + 2] = np.inf
        cost[rng.random(cost.shape) < 0.01] *= 2.0  # and some costs rising elsewhere
        start = repaired.cells[min(3, len(repaired.cells) - 1)]
        if not np.isfinite(cost[start]):
            break
        assert planner.update_costs(cost)  # costs only rose: the field is kept
        fresh = astar(cost, start, goal, factors=factors)
        repaired = planner.plan(start, goal)
        assert repaired.cost == pytest.approx(fresh.cost, rel=1e-12)
        assert repaired.cells[0] == start and repaired.cells[-1] == goal
        assert repaired.expanded < fresh.expanded
    assert planner.stats.fields_built == 1


def test_falling_costs_drop_the_field_and_plans_stay_optimal() -> None:
    cost = _random_map(7)
    goal = (29, 39)
    planner = RepairingPlanner(cost)
    planner.plan((0, 0), goal)
    cheaper = cost.copy()
    cheaper[np.isfinite(cheaper)] = 1.0  # every cost fell: the old field would overestimate
    assert not planner.update_costs(cheaper)
    assert planner.stats.fields_dropped == 1
    assert planner.plan((0, 0), goal).cost == pytest.approx(astar(cheaper, (0, 0), goal).cost, rel=1e-12)
    assert planner.stats.fields_built == 2


def test_bad_goal_is_a_planning_error() -> None:
    with pytest.raises(PlanningError, match="outside"):
        cost_to_go_field(np.ones((4, 4)), (9, 9))
    with pytest.raises(PlanningError, match="shape"):
        astar(np.ones((4, 4)), (0, 0), (3, 3), field=np.zeros((3, 3)))


def test_ties_on_a_flat_map_do_not_flood_it() -> None:
    # Equal costs everywhere: without tie-breaking towards the larger g, A* expands every tied cell.
    for goal in [(299, 299), (0, 299), (299, 0)]:
        result = astar(np.ones((300, 300)), (0, 0), goal)
        assert result.expanded <= 2 * len(result.cells)


def test_work_arrays_kept_between_plans_do_not_leak_one_plan_into_the_next() -> None:
    # Many plans on one planner (the stamps tell each plan's cells apart), one of them from a walled-in
    # start that fails: each cost must still equal a fresh A* from scratch.
    cost = _random_map(11, (40, 40))
    cost[20:23, 20:23] = np.inf
    cost[21, 21] = 1.0  # a free cell walled in by its eight neighbours
    goal = (39, 39)
    planner = RepairingPlanner(cost)
    rng = np.random.default_rng(11)
    free = np.argwhere(np.isfinite(cost_to_go_field(cost, goal)))  # cells the goal can be reached from
    starts = [(int(free[i][0]), int(free[i][1])) for i in rng.choice(len(free), 8, replace=False)]
    starts.insert(4, (21, 21))
    for start in starts:
        if start == (21, 21):
            with pytest.raises(NoPathError):
                planner.plan(start, goal)
            continue
        repaired = planner.plan(start, goal)
        assert repaired.cost == pytest.approx(astar(cost, start, goal, search="heap").cost, rel=1e-12)
        assert repaired.cells[0] == start and repaired.cells[-1] == goal
    assert planner.stats.fields_built == 1


def test_bad_new_costs_are_planning_errors() -> None:
    planner = RepairingPlanner(np.ones((5, 6)))
    with pytest.raises(PlanningError, match="shape"):
        planner.update_costs(np.ones((6, 5)))
    bad = np.ones((5, 6))
    bad[2, 3] = np.nan
    with pytest.raises(PlanningError, match="NaN"):
        planner.update_costs(bad)


def test_windowed_update_takes_exactly_the_windows_costs() -> None:
    """Given where the costs may differ, the planner checks and copies those cells alone: its plans then
    equal those after a whole-grid update, and a cost that fell inside a window still drops the field."""
    cost = _random_map(5)
    goal = (29, 39)
    windowed, whole = RepairingPlanner(cost), RepairingPlanner(cost)
    windowed.prepare(goal)
    whole.prepare(goal)
    rose = cost.copy()
    rose[10:13, 14:18] = np.inf
    rose[25, 3] += 2.0
    windows = [(10, 13, 14, 18), (24, 27, 2, 5)]
    assert windowed.update_costs(rose, windows=windows) and whole.update_costs(rose)
    for start in [(0, 0), (12, 2), (3, 30)]:
        if np.isfinite(rose[start]):
            assert windowed.plan(start, goal).cost == whole.plan(start, goal).cost
    fell = rose.copy()
    fell[11, 15] = 1.0
    assert not windowed.update_costs(fell, windows=[(11, 12, 15, 16)])
    assert windowed.plan((0, 0), goal).cost == pytest.approx(astar(fell, (0, 0), goal).cost, rel=1e-12)
    # A change outside every window is not looked at: the caller promised there was none.
    outside = fell.copy()
    outside[0, 39] = np.inf
    windowed.update_costs(outside, windows=[])
    assert windowed.plan((0, 0), goal).cost == pytest.approx(astar(fell, (0, 0), goal).cost, rel=1e-12)


def test_bad_windows_and_bad_costs_in_a_window_leave_the_costs_untouched() -> None:
    planner = RepairingPlanner(np.ones((5, 6)))
    with pytest.raises(PlanningError, match="not on the 5 x 6 grid"):
        planner.update_costs(np.ones((5, 6)), windows=[(0, 6, 0, 2)])
    with pytest.raises(PlanningError, match="not on the 5 x 6 grid"):
        planner.update_costs(np.ones((5, 6)), windows=[(3, 2, 0, 2)])
    with pytest.raises(PlanningError, match="four whole numbers"):
        planner.update_costs(np.ones((5, 6)), windows=[(0, 2.5, 0, 2)])  # type: ignore[list-item]
    with pytest.raises(PlanningError, match="four whole numbers"):
        planner.update_costs(np.ones((5, 6)), windows=[(0, 2, 0)])  # type: ignore[list-item]
    raised = np.full((5, 6), 3.0)
    raised[4, 5] = np.nan  # in the second window: the first window's rise must not be taken either
    with pytest.raises(PlanningError, match="NaN"):
        planner.update_costs(raised, windows=[(0, 2, 0, 2), (4, 5, 4, 6)])
    assert planner.plan((0, 0), (4, 5)).cost == pytest.approx(astar(np.ones((5, 6)), (0, 0), (4, 5)).cost)


@pytest.mark.parametrize("spread", [4.0, 500.0])
def test_bucket_field_equals_the_heap_field(spread: float) -> None:
    rng = np.random.default_rng(int(spread))
    cost = 1.0 + (spread - 1.0) * rng.random((25, 31))
    cost[rng.random(cost.shape) < 0.2] = np.inf
    cost[24, 30] = 1.0
    factors = _random_factors(int(spread), cost.shape)
    flat_factors = factors.reshape(8, -1)
    for with_factors in (False, True):
        field = cost_to_go_field(cost, (24, 30), factors if with_factors else None)  # the bucket version
        heap = cost_to_go(cost.ravel(), 31, 24 * 31 + 30, flat_factors, with_factors, SQRT2)
        assert np.isfinite(field).sum() > 100
        np.testing.assert_allclose(field.ravel(), heap, rtol=1e-12)


def test_the_benchmark_repair_rows_agree_with_fresh_plans() -> None:
    from navigator.plan_bench import repair_figures

    figures = repair_figures(64, seed=2, repeats=1)
    for key in ("", "window_", "off_path_", "off_path_window_"):
        assert figures[f"{key}same_cost"], key
    assert figures["window_repair_ms"] > 0.0 and figures["off_path_window_repair_ms"] > 0.0
