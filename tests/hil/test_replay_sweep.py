"""``rover logs replay`` over several recordings and configs: a row a config, every row over the same runs."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from hil.replay_sweep import SweepConfig, replay_sweep, sweep_names
from rover_cli.main import main
from tests.hil.replay_trials import config_of


def test_config_names_stay_unique() -> None:
    paths = [Path("a/rover.toml"), Path("b/rover.toml"), Path("noisy.toml"), Path("c/rover.toml")]
    assert sweep_names(paths) == ["rover", "rover-2", "noisy", "rover-3"]


def test_each_config_gets_a_row_over_every_recording(trials: dict[str, Path], tmp_path: Path) -> None:
    recordings = [trials["small_rocky"], trials["hidden_rock"]]
    configs = [
        SweepConfig("as-run", config_of()),
        SweepConfig("noisy", config_of("[estimator]\ngps_noise_m = 2.0\n")),
    ]
    result = replay_sweep(recordings, configs, tmp_path / "out")
    assert not result.failed and len(result.replays) == 4
    as_run, noisy = result.rows
    assert (as_run.config, as_run.recordings, as_run.with_truth) == ("as-run", 2, 2)
    # Under the config the trials ran with, the replays are the trials: nothing differs.
    assert as_run.wheel_commands_differing_pct == 0.0 and as_run.shift_rms_mean_m == 0.0
    assert as_run.error_rms_mean_m == pytest.approx(as_run.recorded_error_rms_mean_m, abs=1e-12)
    assert noisy.wheel_commands_differing_pct > 0.0 and noisy.shift_rms_mean_m is not None
    assert noisy.shift_rms_mean_m > 0.0 and noisy.error_rms_mean_m != as_run.error_rms_mean_m
    assert noisy.recorded_error_rms_mean_m == as_run.recorded_error_rms_mean_m
    written = sorted(p.relative_to(tmp_path / "out").as_posix() for p in (tmp_path / "out").rglob("*.mcap"))
    assert written == [
        "001-small_rocky-trial/as-run.mcap",
        "001-small_rocky-trial/noisy.mcap",
        "002-hidden_rock-trial/as-run.mcap",
        "002-hidden_rock-trial/noisy.mcap",
    ]


def test_worker_processes_give_the_same_rows(trials: dict[str, Path], tmp_path: Path) -> None:
    recordings = [trials["small_rocky"], trials["hidden_rock"]]
    configs = [SweepConfig("noisy", config_of("[estimator]\ngps_noise_m = 2.0\n"))]
    done: list[Path] = []
    inline = replay_sweep(recordings, configs, tmp_path / "inline")
    pooled = replay_sweep(recordings, configs, tmp_path / "pooled", workers=2, on_done=done.append)
    assert pooled.rows == inline.rows and not pooled.failed
    assert [r.recording for r in pooled.replays] == recordings  # in the order given, whatever finished first
    assert sorted(done) == sorted(recordings)


def test_a_folder_with_a_bad_file_is_replayed_without_it(
    trials: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    campaign = tmp_path / "campaign"
    for name in ("small_rocky", "hidden_rock"):
        (campaign / name).mkdir(parents=True)
        shutil.copy(trials[name], campaign / name / "trial.mcap")
    (campaign / "broken").mkdir()
    (campaign / "broken" / "trial.mcap").write_text("not a recording")
    noisy = tmp_path / "noisy.toml"
    noisy.write_text("[estimator]\ngps_noise_m = 2.0\n")
    out = campaign / "replays"  # inside the folder given: never read back as input
    code = main(["logs", "replay", str(campaign), "--config", str(noisy), "--out", str(out), "--json"])
    assert code == 1  # one recording left out
    document = json.loads(capsys.readouterr().out)
    # The same beside the replays, for scripts, and as a table for people.
    assert json.loads((out / "sweep.json").read_text()) == document
    table = (out / "sweep.md").read_text()
    assert "| noisy | 2 (2) |" in table and f"`{campaign / 'broken' / 'trial.mcap'}`" in table
    assert list(document["failed"]) == [str(campaign / "broken" / "trial.mcap")]
    (row,) = document["rows"]
    assert row["config"] == "noisy" and row["recordings"] == 2 and row["wheel_commands_differing_pct"] > 0.0
    # Again into the same folder: refused whole, the earlier replays left as they are.
    before = sorted(out.rglob("*.mcap"))
    assert main(["logs", "replay", str(campaign), "--config", str(noisy), "--out", str(out)]) == 2
    assert "already holds recordings" in capsys.readouterr().out
    assert sorted(out.rglob("*.mcap")) == before and len(before) == 2


def test_bad_sweep_input_is_refused_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "empty").mkdir()
    good = tmp_path / "good.toml"
    good.write_text("")
    assert (
        main(["logs", "replay", str(tmp_path / "empty"), "--config", str(good), "--out", str(tmp_path / "o")])
        == 2
    )
    assert "no .mcap recording" in capsys.readouterr().out
    (tmp_path / "bad.toml").write_text("[estimator]\ngps_noise_m = -1\n")
    args = [
        "logs",
        "replay",
        str(tmp_path / "empty"),
        "--config",
        str(good),
        "--config",
        str(tmp_path / "bad.toml"),
    ]
    assert main([*args, "--out", str(tmp_path / "o")]) == 2
    assert "gps_noise_m" in capsys.readouterr().out


def test_a_figure_that_could_not_be_compared_is_null_in_the_json() -> None:
    from hil.replay_sweep import SweepResult, SweepRow
    from hil.replay_sweep_summary import sweep_document

    row = SweepRow("c", "c.toml", 1, 0, None, None, None, None, None, 100.0, float("inf"))
    document = sweep_document(SweepResult(rows=[row]))
    assert document["rows"][0]["wheel_speed_difference_max_mps"] is None
    json.dumps(document, allow_nan=False)  # strict JSON: no Infinity
