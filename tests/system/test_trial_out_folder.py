"""`rover hil trial --out DIR` refuses a folder holding an earlier trial's files (exit 2, nothing written),
as `rover hil peer` refuses an earlier truth.mcap: it had replaced trial.mcap and left the old report beside
the new recording. The default folder (logs/trials/<name>-seed<N>) takes a fresh -2 suffix instead."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.trial import METRICS_JSON, TRIAL_MCAP
from rover_cli.hil_commands import TRIAL_FILES
from rover_cli.main import main

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "small_rocky.toml"  # name small-rocky, seed 3


def test_the_files_refused_are_the_ones_a_trial_writes() -> None:
    # The report's three are checked against a real --report run in test_trial.py.
    assert {TRIAL_MCAP, METRICS_JSON} <= set(TRIAL_FILES)


@pytest.mark.parametrize("name", TRIAL_FILES)
def test_an_earlier_trials_file_in_out_is_refused_and_left_as_it_is(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    out = tmp_path / "run"
    out.mkdir()
    (out / name).write_bytes(b"an earlier trial's")
    assert main(["hil", "trial", str(SCENARIO), "--out", str(out), "--no-telemetry"]) == 2
    said = capsys.readouterr().out
    assert f"--out {out}: {out / name} already exists (an earlier trial's" in said, said
    assert "give --out a new folder, or move that file away" in said, said
    assert [p.name for p in out.iterdir()] == [name]  # nothing written
    assert (out / name).read_bytes() == b"an earlier trial's"


def test_every_earlier_file_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    out.mkdir()
    for name in (TRIAL_MCAP, "report.md"):
        (out / name).write_bytes(b"earlier")
    assert main(["hil", "trial", str(SCENARIO), "--out", str(out), "--no-telemetry"]) == 2
    said = capsys.readouterr().out
    assert f"{out / TRIAL_MCAP}, {out / 'report.md'} already exist" in said, said
    assert "move those files away" in said, said


def test_the_default_folder_takes_a_fresh_suffix_beside_an_earlier_trial(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    earlier = tmp_path / "logs" / "trials" / "small-rocky-seed3"
    earlier.mkdir(parents=True)
    (earlier / TRIAL_MCAP).write_bytes(b"the first run")
    # A telemetry endpoint that cannot open stops the command (exit 2) once its folder is made, before the
    # trial runs: enough to see which folder it took, without running one. 192.0.2.1 (TEST-NET-1) is on no
    # interface: binding fails at once and no packet is sent.
    config = tmp_path / "rover.toml"
    config.write_text('[zenoh]\nenabled = true\nlisten = ["tcp/192.0.2.1:0"]\n', encoding="utf-8")
    assert main(["hil", "trial", str(SCENARIO), "--config", str(config)]) == 2
    said = capsys.readouterr().out
    assert "already exist" not in said and "telemetry" in said, said
    assert (tmp_path / "logs" / "trials" / "small-rocky-seed3-2").is_dir()
    assert [p.name for p in earlier.iterdir()] == [TRIAL_MCAP]
    assert (earlier / TRIAL_MCAP).read_bytes() == b"the first run"
