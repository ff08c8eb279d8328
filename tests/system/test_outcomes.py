"""What a test engineer gates on: exit codes, the verdict and its reasons, what a recording says ran.

The trials here are short: the goal sits inside a closed ring of rocks (on free ground: a goal inside an
obstacle is refused at load), so the planner gives up (``no_path``) two simulated seconds in.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil.campaign import load_campaign
from logs.reader import read_attachments, read_metadata
from logs.report import write_report
from logs.settings import ConfigError
from rover_cli.main import main
from tests.system.unreachable_goal import ring_of_rocks

DATA = Path(__file__).resolve().parents[1] / "data"


def _boulder_scenario(tmp_path: Path, success: str = "") -> Path:
    text = (DATA / "small_rocky.toml").read_text(encoding="utf-8")
    text = text.replace("xy = [11.5, 7.5]", "xy = [6.5, 7.5]").replace(
        "duration_s = 45.0", "duration_s = 8.0"
    )
    text += "\n" + ring_of_rocks(6.5, 7.5)
    path = tmp_path / "boulder.toml"
    path.write_text(text + (f"\n[success]\n{success}\n" if success else ""), encoding="utf-8")
    return path


def _campaign(tmp_path: Path, seeds: str = "[1]") -> Path:
    path = tmp_path / "campaign.toml"
    path.write_text(
        f"""
name = "boulder"
seeds = {seeds}
workers = 1

[[terrains]]
name = "rocky"
scenario = "{_boulder_scenario(tmp_path)}"

[[variants]]
name = "terrain-aware"
[variants.overrides]
planner.cost_mode = "terrain"

[[variants]]
name = "classical"
[variants.overrides]
planner.cost_mode = "classical"
""",
        encoding="utf-8",
    )
    return path


def test_failed_trial_prints_each_reason_and_exits_1(tmp_path, capsys):
    scenario = _boulder_scenario(tmp_path, "max_duration_s = 1.0")
    code = main(["hil", "trial", str(scenario), "--no-telemetry", "--out", str(tmp_path / "run")])
    out = capsys.readouterr().out
    assert code == 1
    assert "no_path" in out and "success criteria: FAILED" in out
    assert "goal not reached" in out
    assert "duration 2.0 s > 1 s" in out
    assert "distance to goal at end (m, truth)" in out
    assert (tmp_path / "run" / "metrics.json").is_file()  # the evidence is written all the same


def test_out_that_is_a_file_is_bad_input(tmp_path, capsys):
    existing = tmp_path / "trial.mcap"
    existing.write_bytes(b"not a folder")
    scenario = DATA / "small_rocky.toml"
    assert main(["hil", "trial", str(scenario), "--no-telemetry", "--out", str(existing)]) == 2
    assert "exists and is not a directory" in capsys.readouterr().out
    assert main(["hil", "campaign", str(_campaign(tmp_path)), "--out", str(existing)]) == 2
    assert existing.read_bytes() == b"not a folder"


def test_zenoh_endpoint_that_cannot_open_is_bad_input(tmp_path, capsys):
    config = tmp_path / "rover.toml"
    # 192.0.2.1 (TEST-NET-1) is on no interface here: binding fails at once and no packet is sent (a
    # malformed address such as 999.1.1.1 would go to the DNS resolver first).
    config.write_text('[zenoh]\nenabled = true\nlisten = ["tcp/192.0.2.1:0"]\n', encoding="utf-8")
    code = main(
        ["hil", "trial", str(DATA / "small_rocky.toml"), "--config", str(config), "--out", str(tmp_path)]
    )
    out = capsys.readouterr().out
    assert code == 2
    assert "telemetry" in out and "192.0.2.1" in out and "[zenoh]" in out
    assert not (tmp_path / "trial.mcap").exists()  # refused before the trial started


def test_campaign_without_seeds_is_refused_when_loaded(tmp_path, capsys):
    path = _campaign(tmp_path, seeds="[]")
    with pytest.raises(ConfigError, match=r"campaign\.toml.*seeds"):
        load_campaign(path)
    assert main(["hil", "campaign", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "seeds" in capsys.readouterr().out


def test_campaign_lists_failed_trials_and_recordings_name_their_variant(tmp_path, capsys):
    out_dir = tmp_path / "out"
    assert main(["hil", "campaign", str(_campaign(tmp_path)), "--out", str(out_dir)]) == 1
    printed = capsys.readouterr().out
    assert "success criteria: FAILED in 2 of 2 trials" in printed
    for label in ("rocky/terrain-aware/seed1", "rocky/classical/seed1"):
        assert f"{label} (no_path): goal not reached" in printed
    summary = json.loads((out_dir / "summary.json").read_text(encoding="utf-8"))
    assert all(row["failures"] and not row["success"] for row in summary["table2"])

    recording = out_dir / "rocky" / "classical" / "seed1" / "trial.mcap"
    metadata = read_metadata(recording)
    assert metadata["trial"]["variant"] == "classical"
    assert metadata["trial"]["config"] == "<built-in defaults> + overrides of rocky/classical/seed1"
    assert metadata["config"]["planner.cost_mode"] == "classical"
    attached = json.loads(read_attachments(recording)["config.effective.json"])
    assert attached["planner"]["cost_mode"] == "classical"

    report = write_report([out_dir], tmp_path / "report", plots=False)
    (comparison,) = report.comparisons
    differing = {d["key"] for d in comparison.metadata_differences}
    assert {"config.planner.cost_mode", "trial.variant"} <= differing
    rows = {(row["terrain"], row["variant"]): row["runs"] for row in report.terrain_table}
    assert rows == {("rocky", "classical"): 1, ("rocky", "terrain-aware"): 1}
    # The rover never moves: the distance is start (2, 2) to goal (6.5, 7.5).
    assert "| distance to goal at end (m, truth) | 7.106 |" in report.markdown.read_text(encoding="utf-8")


def test_a_metadata_record_only_one_run_has_is_one_comparison_row():
    from logs.compare import _metadata_differences

    sim = {"trial": {"mode": "sim-lockstep"}, "config": {"planner.cost_mode": "terrain", "rover_id": "r1"}}
    real = {"trial": {"mode": "rover-run"}}
    assert _metadata_differences(sim, real) == [
        {"key": "config.*", "a": "2 keys", "b": None},
        {"key": "trial.mode", "a": "sim-lockstep", "b": "rover-run"},
    ]


def test_a_config_file_with_a_signing_key_is_not_attached(tmp_path):
    # Recordings get shared: the MAVLink signing key must not travel in them, not even in the file's copy.
    from hil.scenario import load_scenario
    from hil.trial import write_header
    from logs.recorder import McapRecorder
    from navigator.config import load_rover_config

    key = "5a" * 32
    config_path = tmp_path / "signed.toml"
    config_path.write_text(f'[mavlink]\nsigning_key = "{key}"\n', encoding="utf-8")
    scenario = load_scenario(_boulder_scenario(tmp_path))
    for name, config in (
        ("signed", load_rover_config(config_path)),
        ("plain", load_rover_config(Path(__file__).resolve().parents[2] / "configs" / "rover.toml")),
    ):
        recording = tmp_path / f"{name}.mcap"
        with McapRecorder(recording) as recorder:
            write_header(recorder, scenario, config, 1)
        attached = read_attachments(recording)
        assert ("config.toml" in attached) == (name == "plain")
        assert key.encode() not in recording.read_bytes()
