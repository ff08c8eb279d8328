"""A rover crossing a muddy side slope slides downhill; the terrain-aware planner goes round.

``tests/data/mud_side_slope.toml``: the direct line runs along a contour of a band tilted 16 deg about it
(over x 5-9.5 m), which a parked rover holds on mud but a driving one does not (docs/physics.md). Classical
A* (obstacles only) drives the line and the recorded truth shows the slide; terrain-aware A* forbids the
line and arrives by the flat mud beyond the band: the band's cells are past mud's climb limit (lethal in
the cost grid, whatever the heading), which keeps every passable cell within what the wheels hold sideways
(``tests/navigator/test_side_slope_invariant.py``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hil.scenario import load_scenario
from hil.trial import TrialResult, run_trial
from logs import topics
from logs.reader import read_messages
from logs.settings import parse_toml
from navigator.config import rover_config_from_table
from navigator.planner import Planner
from navigator.vehicle import VehicleParams

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "mud_side_slope.toml"
LINE_Y = 6.0
FULL_TILT_X = (5.0, 9.5)


def _trial(out: Path, cost_mode: str) -> TrialResult:
    config = rover_config_from_table(parse_toml(f'[planner]\ncost_mode = "{cost_mode}"\n', "<mud>"))
    return run_trial(load_scenario(SCENARIO), config, out)


def _truth(result: TrialResult) -> list[dict]:
    return [m.message for m in read_messages(result.mcap_path, topics={topics.TRUTH_POSE})]


def _xy(pose: dict) -> tuple[float, float]:
    position = pose["pose"]["position"]
    return position["x"], position["y"]


def test_driving_along_the_muddy_side_slope_it_slides_downhill(tmp_path: Path) -> None:
    result = _trial(tmp_path / "classical", "classical")
    poses = _truth(result)
    on_band = [p for p in poses if FULL_TILT_X[0] <= _xy(p)[0] <= FULL_TILT_X[1]]
    assert on_band
    # Before the band, on level mud, it hardly slides (under 1 mm/s: in its first second its wheels spin
    # at full traction, which leaves little sideways, while it straightens up); on the band it slides
    # sideways, downhill (-y: the ground rises to its left), at up to ~0.8 m/s, and ends well below the
    # line it was following.
    assert max(abs(p["lateral_speed_mps"]) for p in poses if _xy(p)[0] < 3.0) < 1e-3
    assert min(p["lateral_speed_mps"] for p in on_band) < -0.5
    assert min(_xy(p)[1] for p in on_band) < LINE_Y - 1.0
    assert max(math.degrees(p["roll_rad"]) for p in on_band) > 15.0  # the slope it could not hold on
    assert result.metrics.rollovers == 0
    cross_track = result.metrics.cross_track_error_max_m
    assert cross_track is not None and cross_track > 1.0


def test_the_terrain_aware_planner_forbids_the_line_and_goes_round(tmp_path: Path) -> None:
    scenario = load_scenario(SCENARIO)
    row = scenario.believed_terrain.cell_of(7.0, LINE_Y)[0]
    cols = [scenario.believed_terrain.cell_of(x, LINE_Y)[1] for x in np.arange(5.5, 9.0, 0.25)]
    planner = Planner(scenario.believed_terrain, VehicleParams())
    assert np.isinf(np.asarray(planner.cost_grid)[row, cols]).all()  # mud climbs 5.5 deg; the band is 16

    result = _trial(tmp_path / "terrain", "terrain")
    assert result.metrics.goal_reached and result.metrics.rollovers == 0, result.metrics
    poses = _truth(result)
    on_band_x = [p for p in poses if FULL_TILT_X[0] <= _xy(p)[0] <= FULL_TILT_X[1]]
    assert on_band_x and all(abs(_xy(p)[1] - LINE_Y) > 2.5 for p in on_band_x)  # round the band
    assert max(abs(p["lateral_speed_mps"]) for p in poses) < 1e-3
