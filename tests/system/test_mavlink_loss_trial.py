"""A MAVLink link loss in a lockstep trial: the rover stops on its lost attitude first, a second before the
heartbeat's budget runs out, and the soak's judge explains every failsafe the loss raised."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.scenario import load_scenario
from hil.soak_plan import CATALOG, SoakFault
from hil.soak_report import NS, _judge_fault, unexplained_failsafes
from hil.trial import TrialResult, run_trial
from logs.reader import read_messages
from logs.topics import SAFETY_EVENTS
from navigator.config import RoverConfig

DATA = Path(__file__).resolve().parents[1] / "data"
START_S = 6.0  # mid-drive: the rover drives from 2 s and arrives after 20 s
# The soak's MAVLink loss, as its catalog plans it.
(MAVLINK_OFF,) = [
    SoakFault(target, kind, START_S, length, evidence, failsafe)
    for target, kind, length, evidence, failsafe in CATALOG
    if (target, kind) == ("mavlink", "off")
]
TICK_S = 0.02
ATTITUDE_PERIOD_S = 0.1  # the simulated AHRS's 10 Hz


@pytest.fixture(scope="module")
def trial(default_config: RoverConfig, tmp_path_factory: pytest.TempPathFactory) -> TrialResult:
    text = (DATA / "small_rocky.toml").read_text(encoding="utf-8")
    text += (
        f'\n[[faults]]\ntarget = "mavlink"\nkind = "off"\nstart_s = {START_S}\n'
        f"duration_s = {MAVLINK_OFF.duration_s}\n"
    )
    path = tmp_path_factory.mktemp("mavlink-off") / "scenario.toml"
    path.write_text(text, encoding="utf-8")
    return run_trial(load_scenario(path), default_config, path.parent / "run")


def _events(trial: TrialResult) -> list[tuple[int, str, str]]:
    return [
        (m.log_time_ns, str(m.message["kind"]), str(m.message["detail"]))
        for m in read_messages(trial.mcap_path, [SAFETY_EVENTS])
    ]


def _first_s(events: list[tuple[int, str, str]], kind: str) -> float:
    times = [t / NS for t, k, _ in events if k == kind]
    assert times, f"no {kind}"
    return times[0]


def test_the_rover_stops_on_its_lost_attitude_before_the_heartbeat_and_drives_on(trial: TrialResult) -> None:
    assert trial.success, trial.failures
    events = _events(trial)
    # The last attitude came within one period before the loss; one tick past 1 s after it, the hold.
    lost = _first_s(events, "failsafe.attitude_lost")
    assert START_S + 1.0 - ATTITUDE_PERIOD_S < lost <= START_S + 1.0 + TICK_S + 1e-9
    holds = [(t / NS, detail) for t, kind, detail in events if kind == "mode" and "-> HOLD" in detail]
    assert holds[0] == (lost, "DRIVING -> HOLD: attitude_lost"), holds
    assert lost + 1.0 < _first_s(events, "failsafe.heartbeat_lost") <= MAVLINK_OFF.end_s
    # Cleared by the first attitude after the link is back (10 Hz; one sent as it ends is read at once).
    cleared = _first_s(events, "cleared.attitude_lost")
    assert MAVLINK_OFF.end_s <= cleared <= MAVLINK_OFF.end_s + ATTITUDE_PERIOD_S + TICK_S + 1e-9


def test_the_soak_judge_sees_the_loss_and_explains_each_failsafe_it_raised(trial: TrialResult) -> None:
    events = _events(trial)
    window = (START_S * NS, MAVLINK_OFF.end_s * NS)
    result = _judge_fault(MAVLINK_OFF, window, [(t, kind) for t, kind, _ in events], [], 0.0)
    assert result.seen and result.recovered, result
    failsafes = [event for event in events if event[1].startswith("failsafe.")]
    assert {kind for _, kind, _ in failsafes} >= {"failsafe.attitude_lost", "failsafe.heartbeat_lost"}
    assert unexplained_failsafes(failsafes, [(MAVLINK_OFF, window)], [], 0.0) == []
