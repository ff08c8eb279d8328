"""The planner's oriented-footprint post-check over the circle-inflated A* path."""

import logging

import numpy as np
import pytest

from navigator.errors import NoPathError, PlanningError
from navigator.footprint import Footprint, first_collision
from navigator.planner import ESCAPE_RADIUS_M, Planner
from navigator.terrain import TerrainMap
from navigator.vehicle import VehicleParams

PARAMS = VehicleParams()  # 0.9 x 0.7 m
ROVER = Footprint.of(PARAMS)


def _map(obstacles: np.ndarray, res: float) -> TerrainMap:
    shape = obstacles.shape
    return TerrainMap(np.zeros(shape), np.zeros(shape, np.uint8), obstacles, res)


def _checked(planner: Planner, start: tuple[float, float], goal: tuple[float, float]) -> None:
    """Plan; a returned path's rectangle must not touch an obstacle past the rover's first cell centre."""
    path = planner.plan(start, goal)
    # Unchecked: only the way onto the grid, to the start cell's centre or an escape cell's.
    assert path.checked_from_m <= ESCAPE_RADIUS_M + planner.terrain.resolution_m
    assert first_collision(path.points, planner.terrain, ROVER, skip_m=path.checked_from_m) is None


def test_inscribed_inflation_squeezes_lengthwise_where_the_circumscribed_circle_cannot() -> None:
    walls = np.ones((40, 80), dtype=bool)  # 8 x 4 m at 0.1 m
    walls[16:27, :] = False  # a 1.1 m corridor: wider than the rover + 2 x 0.1 m, narrower than its diagonal
    terrain = _map(walls, 0.1)
    with pytest.raises(PlanningError, match="lethal"):  # the circle blocks the whole corridor
        Planner(terrain, PARAMS, cost_mode="classical").plan((1.0, 2.15), (7.0, 2.15))
    squeezing = Planner(terrain, PARAMS, cost_mode="classical", footprint_inflation="inscribed")
    path = squeezing.plan((1.0, 2.15), (7.0, 2.15))
    assert path.length_m == pytest.approx(6.0)
    _checked(squeezing, (1.0, 2.15), (7.0, 2.15))
    with pytest.raises(PlanningError, match="footprint inflation"):
        Planner(terrain, PARAMS, footprint_inflation="square")


def test_inscribed_inflation_raises_when_the_rectangle_cannot_turn_in_a_bend() -> None:
    # An L-shaped 1.1 m corridor: the inscribed circle (0.35 + 0.1 m) fits round the bend, the rectangle
    # turning on the spot there (corner reach 0.57 m, walls 0.55 m away) does not, and there is no other way.
    walls = np.ones((50, 50), dtype=bool)
    walls[5:16, 5:45] = False  # east-west leg, y 0.5-1.6
    walls[5:45, 34:45] = False  # north-south leg, x 3.4-4.5
    planner = Planner(_map(walls, 0.1), PARAMS, cost_mode="classical", footprint_inflation="inscribed")
    with pytest.raises(NoPathError, match=r"footprint does not fit: it hits an obstacle at \(3\.95, 1\.05\)"):
        planner.plan((1.2, 1.05), (3.95, 4.0))


@pytest.mark.parametrize("inflation", ["circumscribed", "inscribed"])
def test_no_returned_path_lets_the_rectangle_hit_on_seeded_random_maps(
    inflation: str, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG, logger="navigator.planner")
    rng = np.random.default_rng(11)
    planned = 0
    for _ in range(25):
        walls = np.zeros((48, 48), dtype=bool)  # 12 x 12 m at 0.25 m
        for _ in range(int(rng.integers(4, 12))):
            row, col = rng.integers(0, 48, size=2)
            height, width = rng.integers(1, 10, size=2)
            walls[row : row + height, col : col + width] = True
        terrain = _map(walls, 0.25)
        planner = Planner(terrain, PARAMS, cost_mode="classical", footprint_inflation=inflation)
        for _ in range(4):
            start, goal = (tuple(rng.uniform(0.8, 11.2, size=2)) for _ in range(2))
            try:
                _checked(planner, start, goal)
                planned += 1
            except PlanningError:
                continue  # start / goal in an obstacle or walled off: nothing returned to check
    assert planned >= 30  # the loop checked real paths, not only refusals
    retries = sum("footprint hits" in record.message for record in caplog.records)
    if inflation == "inscribed":
        assert retries > 0  # the optimistic circle let A* into places the rectangle does not fit
