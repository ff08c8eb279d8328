"""Loading every compiled kernel the onboard stack runs before its clock starts.

On a machine's first run numba compiles them (seconds); after that they load from its cache (ms). Either
way it must not happen inside the first ticks: in real time the stall failsafe fired on start-up, and in
a lockstep trial the real-time factor of a first run counted the compiling.
"""

from __future__ import annotations

import logging

import numpy as np

from estimator.ekf import load_kernels
from logs.clock import Clock
from navigator.config import RoverConfig
from navigator.errors import NavigatorError
from navigator.planner import Planner
from navigator.projection_kernel import nearest_segment

_log = logging.getLogger(__name__)


def warm_up(planner: Planner, config: RoverConfig, clock: Clock) -> None:
    """Before the loop starts, load (or, on a machine's first run, compile) every kernel the process runs,
    so none is compiled inside a tick: the EKF's predict and update, the follower's path projection, the
    terrain look-up under the rover, and the A* kernels (one plan on this map). On a cold numba cache the
    control kernels compiled inside the first ticks (a ~3 s stall: the stall failsafe fired on start-up),
    and a first plan compiled for seconds (on the planning thread it holds the rover in PLANNING as long).
    A map with no free cell leaves the terrain look-up and the plan to guidance."""
    load_kernels(config.estimator)
    nearest_segment(np.array([[0.0, 0.0], [1.0, 0.0]]), 0, 1, 0.5, 0.5)
    free = np.argwhere(np.isfinite(planner.cost_grid))
    if free.size == 0:
        return
    cell = (int(free[0][0]), int(free[0][1]))
    x, y = planner.terrain.center_of(*cell)
    planner.terrain.ground_at(x, y, 0.0)
    started = clock.now_ns()
    try:
        planner.plan_cells(cell, cell)
    except NavigatorError as err:
        _log.warning("planner warm-up failed (the first plan will be slow): %s", err)
        return
    _log.info("planner warmed up in %.2f s", (clock.now_ns() - started) / 1e9)
