"""The onboard stack learns from a slide (navigator.onboard_learning, navigator.slide_learning): driving its
route across a sandy side slope while its GPS shows it sliding downhill, it learns sand's friction once,
tells it, records it and plans the goal again without stopping; off, or in classical mode, it does not.

On the lockstep rig (real stack, simulated rover, fake clock and links) on a map tilted 10 deg about the
start-goal line, sandy across the middle, with the ATTITUDE roll the ground's and the GPS's ground track
given a slide downhill while the rover is on the sand (the table's sand holds the simulated rover on 10 deg:
the slide is put where a real one shows, in what the autopilot reports)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from hil.autopilot_sim import AutopilotTruth
from navigator.route_guidance import Mode
from navigator.terrain import TerrainMap
from navigator.terrain_classes import FIRM, SANDY
from tests.runtime.rig import Rig, rig_config

TILT = math.radians(10.0)
RESOLUTION_M = 0.25
SAND_X = (7.0, 13.0)
SLIDE_MPS = -0.3  # to the right, downhill of a rover heading east on ground rising to the north


def _slope() -> TerrainMap:
    """20 x 40 m, rising to the north at 10 deg for y 5-35 m (flat beyond), sandy for x 7-13 m: the
    start-goal line y = 20 runs along a contour across the sand; flat ground far south and north goes
    round (15 m down the slope and back: the planner prefers the side slope until it learns)."""
    ys, xs = (np.mgrid[0:160, 0:80] + 0.5) * RESOLUTION_M
    elevation = np.clip(ys, 5.0, 35.0) * math.tan(TILT)
    classes = np.where((xs >= SAND_X[0]) & (xs < SAND_X[1]), SANDY, FIRM).astype(np.uint8)
    return TerrainMap(elevation, classes, np.zeros(elevation.shape, bool), RESOLUTION_M)


def _rig(**planner: Any) -> Rig:
    config = rig_config()
    config = dataclasses.replace(config, planner=dataclasses.replace(config.planner, **planner))
    rig = Rig(config, start=(2.0, 20.0), goal=(18.0, 20.0), terrain=_slope())
    step: Callable[[AutopilotTruth], None] = rig.autopilot.step
    body, terrain = rig.body, rig.terrain

    def sliding(truth: AutopilotTruth) -> None:
        roll, pitch = terrain.tilt_at(body.x, body.y, body.yaw)
        on_sand = SAND_X[0] + 0.5 <= body.x <= SAND_X[1] - 0.5 and 16.0 <= body.y <= 24.0
        slide = SLIDE_MPS if on_sand and body.speed > 0.3 else 0.0
        step(truth._replace(roll_rad=roll, pitch_rad=pitch, lateral_speed_mps=slide))

    rig.autopilot.step = sliding  # type: ignore[method-assign]
    return rig


def _learned(rig: Rig) -> list[dict[str, Any]]:
    return [m for topic, _t, m in rig.sink.records if topic == "navigator/learned"]


def test_sliding_down_the_sand_it_learns_once_and_plans_again_driving_on() -> None:
    rig = _rig()
    try:
        believed = rig.stack.guidance.classes[SANDY].friction_mu
        rig.run_until(lambda: bool(rig.events("learned.terrain")), 40.0, "a learning")
        learned_ns = rig.now_ns
        ((_t, told),) = rig.events("learned.terrain")
        assert told["detail"].startswith("slid sideways across 10.")
        assert "deg on sandy: friction_mu" in told["detail"] and "planning again" in told["detail"]
        (record,) = _learned(rig)
        assert record["class_name"] == "sandy" and record["field"] == "friction_mu"
        assert record["believed"] == believed and record["value"] < believed
        assert record["slope_rad"] == pytest.approx(TILT, abs=math.radians(1.0))
        # The planner now stops a degree below the roll it slid on.
        assert math.degrees(record["plans_up_to_rad"]) == pytest.approx(
            math.degrees(record["slope_rad"]) - 1.0, abs=1e-9
        )
        assert rig.stack.guidance.classes[SANDY].friction_mu == record["value"]
        # No hold and no wait for the plan: it drives on, and the next tick brings the new plan.
        rig.run_for(1.0)
        states = [m for topic, t, m in rig.sink.records if topic == "navigator/state" and t >= learned_ns]
        assert {s["mode"] for s in states} == {"DRIVING"}
        assert {s["safety_mode"] for s in states} == {"DRIVING"}
        paths = [t for topic, t, _m in rig.sink.records if topic == "navigator/path" and t > learned_ns]
        assert paths and paths[0] == learned_ns + 20_000_000
        # Still sliding on the sand it learned, now on a slope its belief forbids (it is leaving it): a
        # slide there says nothing new, so once.
        rig.run_for(10.0)
        assert len(_learned(rig)) == 1 and len(rig.events("learned.terrain")) == 1
        assert rig.stack.mode in (Mode.DRIVING, Mode.ARRIVED)
    finally:
        rig.close()


@pytest.mark.parametrize("planner", [{"learn_traction": False}, {"cost_mode": "classical"}])
def test_off_or_classical_it_learns_nothing(planner: dict[str, Any]) -> None:
    rig = _rig(**planner)
    try:
        rig.run_for(20.0)
        assert not rig.events("learned.terrain") and not _learned(rig)
        assert rig.stack.guidance.classes[SANDY].friction_mu == 0.4
    finally:
        rig.close()
