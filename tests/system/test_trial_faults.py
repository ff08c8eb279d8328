"""A scenario's faults run in a lockstep trial, or the trial fails naming each one that did not.

After its last ARRIVED the trial goes on, the rover parked, until every fault has run its course; a trial
that ends otherwise first (NO_PATH here: the goal sits inside a ring of rocks, the planner gives up two
simulated seconds in) names each fault it never started or cut short, in the trial's verdict, in its
recording and in the campaign summary.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil.scenario import Scenario, load_scenario
from hil.trial import SETTLE_MAX_NS, TrialResult, run_trial
from logs.reader import read_messages
from logs.topics import LOG, SAFETY_EVENTS
from navigator.config import RoverConfig
from rover_cli.main import main
from tests.system.unreachable_goal import ring_of_rocks

DATA = Path(__file__).resolve().parents[1] / "data"
GPS_OFF_AFTER_ARRIVAL = '\n[[faults]]\ntarget = "gps"\nkind = "off"\nstart_s = 30.0\nduration_s = 5.0\n'
NEVER_RUN = "fault gps/off at 5.0 s never ran: the trial ended at NO_PATH"
CUT_SHORT = "fault imu/stuck from 1.0 s to 6.0 s was cut short: the trial ended at NO_PATH"


def _scenario(tmp_path: Path, extra: str, *, boulder: bool = False) -> Path:
    text = (DATA / "small_rocky.toml").read_text(encoding="utf-8")
    if boulder:
        text = text.replace("xy = [11.5, 7.5]", "xy = [6.5, 7.5]").replace(
            "duration_s = 45.0", "duration_s = 8.0"
        )
        text += "\n" + ring_of_rocks(6.5, 7.5)
    path = tmp_path / "scenario.toml"
    path.write_text(text + extra, encoding="utf-8")
    return path


def _boulder_with_faults(tmp_path: Path) -> Path:
    extra = (
        "\n[success]\ngoal_reached = false\n"  # NO_PATH alone passes: only the faults can fail it
        '\n[[faults]]\ntarget = "gps"\nkind = "off"\nstart_s = 5.0\nduration_s = 1.0\n'
        '\n[[faults]]\ntarget = "imu"\nkind = "stuck"\nstart_s = 1.0\nduration_s = 5.0\n'
    )
    return _scenario(tmp_path, extra, boulder=True)


def _logged(result: TrialResult, name: str) -> list[tuple[float, str]]:
    return [
        (m.log_time_ns / 1e9, str(m.message["message"]))
        for m in read_messages(result.mcap_path, [LOG])
        if m.message["name"] == name
    ]


def test_a_fault_after_the_arrival_runs_with_the_rover_parked(
    small_scenario: Scenario, default_config: RoverConfig, small_trial: TrialResult, tmp_path: Path
) -> None:
    scenario = load_scenario(_scenario(tmp_path, GPS_OFF_AFTER_ARRIVAL))
    result = run_trial(scenario, default_config, tmp_path / "run")
    assert result.end_reason == "arrived" and result.success, result.failures
    assert result.arrived_s is not None and result.arrived_s < 30.0 <= 35.0 <= result.simulated_s
    assert result.parked_until_s == pytest.approx(35.0)
    faults = _logged(result, "hil.faults")
    assert [message for _t, message in faults] == [
        "fault injected: gps/off (from 30 s to 35 s)",
        "fault cleared: gps/off",
    ]
    # The parked rover met the fault: its GPS failsafe fired while it stood at the goal.
    lost = [
        m.log_time_ns / 1e9
        for m in read_messages(result.mcap_path, [SAFETY_EVENTS])
        if m.message["kind"] == "failsafe.gps_lost"
    ]
    assert lost and 30.0 < lost[0] < 35.0
    # The drive is the same drive: standing at the goal does not count in its duration.
    assert small_trial.arrived_s == result.arrived_s
    assert result.metrics.duration_s == small_trial.metrics.duration_s
    # No faults: it stops once the rover has come to rest after the arrival (hil.trial.SETTLE_MAX_NS).
    assert small_trial.parked_until_s is None  # coming to rest is not parking for faults
    assert small_trial.arrived_s is not None
    assert small_trial.arrived_s < small_trial.simulated_s <= small_trial.arrived_s + SETTLE_MAX_NS / 1e9


def test_faults_the_trial_did_not_run_fail_it_with_their_names(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = _boulder_with_faults(tmp_path)
    code = main(["hil", "trial", str(scenario), "--no-telemetry", "--out", str(tmp_path / "run")])
    out = capsys.readouterr().out
    assert code == 1 and "success criteria: FAILED" in out
    assert NEVER_RUN in out and CUT_SHORT in out
    assert "goal not reached" not in out
    recording = tmp_path / "run" / "trial.mcap"
    logged = [
        str(m.message["message"]) for m in read_messages(recording, [LOG]) if m.message["name"] == "hil.trial"
    ]
    assert any(NEVER_RUN in m for m in logged) and any(CUT_SHORT in m for m in logged)


def test_a_campaign_summary_carries_the_faults_a_trial_did_not_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    campaign = tmp_path / "campaign.toml"
    campaign.write_text(
        f'name = "faults"\nseeds = [1]\nworkers = 1\n\n[[terrains]]\nname = "rocky"\n'
        f'scenario = "{_boulder_with_faults(tmp_path)}"\n\n[[variants]]\nname = "terrain-aware"\n',
        encoding="utf-8",
    )
    out_dir = tmp_path / "out"
    assert main(["hil", "campaign", str(campaign), "--out", str(out_dir)]) == 1
    printed = capsys.readouterr().out
    assert "rocky/terrain-aware/seed1 (no_path): fault gps/off at 5.0 s never ran" in printed
    (row,) = json.loads((out_dir / "summary.json").read_text(encoding="utf-8"))["table2"]
    assert not row["success"] and any(NEVER_RUN in f for f in row["failures"])
    assert any(CUT_SHORT in f for f in row["failures"])
    assert CUT_SHORT in (out_dir / "summary.md").read_text(encoding="utf-8")
