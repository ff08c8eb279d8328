"""Estimator accuracy in seeded lockstep HIL trials, one per terrain class, with default sensor noise.

The whole stack runs (simulated VESCs on CAN, simulated autopilot on MAVLink, the onboard loop); the
estimate recorded on ``estimator/pose`` is compared with ``truth/pose`` at the same stamps, from the MCAP.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.scenario import load_scenario
from hil.trial import run_trial
from logs.settings import parse_toml
from navigator.config import rover_config_from_table
from tests.estimator.hil_accuracy import pose_errors

DATA = Path(__file__).resolve().parent / "data"
# The first fix and the AHRS heading prior are absorbed within a second or two; judge what follows.
SETTLED_S = 2.0


@pytest.mark.parametrize("terrain", ["rocky", "sandy", "muddy"])
def test_position_and_heading_rmse_per_terrain(terrain, tmp_path):
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    result = run_trial(load_scenario(DATA / f"{terrain}.toml"), config, tmp_path, seed=5)
    errors = pose_errors(result.mcap_path)
    assert errors.t_s[-1] > 20.0, f"{terrain}: too short a trial to judge ({result.end_reason})"
    position_rmse, heading_rmse = errors.rmse(after_s=SETTLED_S)
    assert position_rmse <= 0.5, f"{terrain}: position RMSE {position_rmse:.3f} m"
    assert heading_rmse <= 3.0, f"{terrain}: heading RMSE {heading_rmse:.2f} deg"
