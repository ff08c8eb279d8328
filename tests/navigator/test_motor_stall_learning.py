"""A climb the motors' torque cannot make is no lesson about the ground (navigator.climb_learning).

On the lockstep rig (real stack, simulated rover) the rover's route runs up 15 deg of firm ground, which the
planner believes (and the simulated ground is) good for ~35 deg; the simulated motors' current limit is set
to 1.5 A, whose pull (19.1 N a wheel) falls between what the climb needs (19.5 N) and what rolling back
needs (18.5 N, the closed forms in tests/hil/test_motor_current_limit.py): the rover stalls on the flank.
The learning must not take the stall for slippery ground: the VESCs report the wheels nearly still
(hil.motor_current), so the stack holds the rover as stuck where it stands (no_progress's "wheels turning",
climb_learning's guard, does not apply). Before, the wheels were reported at the speed commanded while the
rover rolled back to the foot: no_progress with "slipping or dug in", and a back-out marking a dug-in spot.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from hil.dynamics import RoverDynamics
from navigator.terrain import TerrainMap
from navigator.terrain_classes import FIRM
from tests.runtime.rig import Rig, rig_config

SLOPE_RAD = math.radians(15.0)
RESOLUTION_M = 0.25
START, GOAL = (2.0, 10.0), (18.0, 10.0)


def _flank() -> TerrainMap:
    """20 x 20 m of firm ground, flat for x < 5 m, rising east at 15 deg to x = 15 m, flat beyond."""
    _ys, xs = (np.mgrid[0:80, 0:80] + 0.5) * RESOLUTION_M
    elevation = (np.clip(xs, 5.0, 15.0) - 5.0) * math.tan(SLOPE_RAD)
    return TerrainMap(
        elevation, np.full(elevation.shape, FIRM, np.uint8), np.zeros(elevation.shape, bool), RESOLUTION_M
    )


@pytest.fixture
def rig() -> Iterator[Rig]:
    config = rig_config()
    made = Rig(config, start=START, goal=GOAL, terrain=_flank())
    # The simulated rover with its motors' current limit at 1.5 A (the rig's own has the default 10 A).
    made.body = RoverDynamics(
        made.terrain, config.vehicle, x=START[0], y=START[1], yaw=0.0, motor_current_limit_a=1.5
    )
    yield made
    made.close()


def test_a_motor_stall_on_firm_ground_teaches_nothing(rig: Rig) -> None:
    """The stalled rover is held as stuck (its estimated speed, from GPS and the wheels the VESCs report
    nearly still, stays under the stuck check's 0.05 m/s), on the flank, and learns nothing in 15 s more.
    (Before the current limit held the wheels, this failed: the rover was at the foot, x 4.9 m, held for
    no_progress.)"""
    held = ("failsafe.stuck", "failsafe.no_progress")
    rig.run_until(lambda: any(rig.events(kind) for kind in held), 60.0, "a hold")
    assert 5.5 < rig.body.x < 15.0  # on the flank, below its top
    assert rig.events("failsafe.stuck")
    rig.run_for(15.0)
    assert not rig.events("learned.terrain")
    # What the VESCs measure and report: the wheels nearly still.
    assert max(abs(e) / rig.vescs.profile.erpm_per_mps for e in rig.vescs.erpm()) < 0.05
