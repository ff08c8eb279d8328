"""Start-up warm-up: the control tick's compiled kernels are exercised before the real-time loop."""

from __future__ import annotations

import numpy as np

from logs.clock import SimClock
from logs.settings import parse_toml
from navigator.config import rover_config_from_table
from navigator.planner import Planner
from navigator.terrain import from_maze
from navigator.vehicle import VehicleParams
from navigator.warm_up import warm_up


def test_warm_up_runs_every_control_kernel_on_a_map_and_on_one_with_no_free_cell() -> None:
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    free = Planner(from_maze(np.full((6, 6), 2), 1.0), VehicleParams())
    walls = Planner(from_maze(np.ones((6, 6), dtype=int), 1.0), VehicleParams())
    assert np.isfinite(free.cost_grid).any() and not np.isfinite(walls.cost_grid).any()
    warm_up(free, config, SimClock())
    warm_up(walls, config, SimClock())  # nothing to look up or plan on: skipped, no error
