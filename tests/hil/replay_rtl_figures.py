"""The replay figures docs/reports.md quotes for a trial with a ground station on a link of its own: the RTL
trial of ``test_a_mission_ending_in_return_to_launch_brings_the_rover_home`` (small_rocky_waypoints, a
waypoint then a return to launch uploaded over MAVLink, the default config) run, replayed with
``hil.replay.replay_recording`` under ``config_of()``, and compared topic by topic with ``digests``.

Run from the worktree root: ``.venv/bin/python -m tests.hil.replay_rtl_figures OUT_DIR`` (OUT_DIR new or
empty): it writes the trial and ``replay.mcap`` there and prints the figures. Not a test: the figures are
a report's, the properties ``tests/hil/test_replay.py`` checks.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pymap3d

from hil.replay import replay_recording
from hil.scenario import load_scenario
from hil.trial import run_trial
from logs.settings import parse_toml
from navigator.config import rover_config_from_table
from tests.firmware_bridge.ground_station import ScriptedGroundStation, return_to_launch, waypoint
from tests.hil.replay_trials import DATA, config_of, digests
from tests.hil.test_mission_trial import FAST_LEG


def main(out_dir: Path) -> list[str]:
    """Run the trial into ``out_dir``, replay it there; the figures, a line each."""
    scenario = load_scenario(DATA / "small_rocky_waypoints.toml")
    away = pymap3d.enu2geodetic(*FAST_LEG, 0.0, *scenario.datum)[:2]
    station = ScriptedGroundStation([waypoint(0, *away), return_to_launch(1)])
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    trial = run_trial(scenario, config, out_dir / "trial", ground_station=station)
    replay = replay_recording(trial.mcap_path, config_of(), out_dir / "replay.mcap")
    lines = [
        f"trial ended: {trial.end_reason}",
        f"wheel commands differing: {replay.wheel_commands_differing} of {replay.wheel_commands_compared}",
    ]
    recorded, replayed = digests(trial.mcap_path), digests(replay.out_path)
    for topic in sorted(recorded.keys() | replayed.keys()):
        before, after = recorded.get(topic, (0, "")), replayed.get(topic, (0, ""))
        if before != after:
            same = "same bytes" if before[1] == after[1] else "other bytes"
            lines.append(f"{topic}: {before[0]} recorded, {after[0]} replayed, {same}")
    lines.append(f"every other of the {len(recorded)} recorded topics the same")
    return lines


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path)
    args = parser.parse_args()
    args.out_dir.mkdir(parents=True, exist_ok=True)
    sys.stdout.write("\n".join(main(args.out_dir)) + "\n")
