"""`rover logs report` given a path that is no recording (a typo, a scenario in a recording's place) refuses
before writing anything; it once wrote an empty report and advised `rover logs recover`. A cut file is
warned of once, and report.md says where its plots are."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from logs.report import PLOTS_IN_HTML, write_report
from rover_cli.main import main
from tests.logs.damaged_recording import write_small_trial
from tests.logs.realtime_pair import write_pair

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_small_trial(tmp_path_factory.mktemp("report") / "trial.mcap")


@pytest.mark.parametrize(
    ("given", "what"),
    [
        ("absent.mcap", "does not exist"),
        (str(REPO / "scenarios" / "default.toml"), "is a TOML scenario (it has [terrain] and [start];"),
        (str(REPO / "configs" / "rover.toml"), "is a TOML rover config (it has [vehicle] and [vesc])"),
        (str(REPO / "campaigns" / "paper.toml"), "is a TOML campaign (it has [[terrains]] and [[variants]];"),
        ("notes.mcap", "is not an MCAP file (it starts with b'hello, n')"),
    ],
    ids=["missing", "scenario", "config", "campaign", "other bytes"],
)
def test_a_path_that_is_no_recording_is_refused_with_nothing_written(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], given: str, what: str
) -> None:
    (tmp_path / "notes.mcap").write_text("hello, not a recording\n")
    path = Path(given) if Path(given).is_absolute() else tmp_path / given
    out = tmp_path / "out"
    # Beside a good recording too: a path given by mistake is a bad argument, not a run to leave out.
    assert main(["logs", "report", str(recording), str(path), "--out", str(out), "--no-plots"]) == 2
    printed = " ".join(capsys.readouterr().out.split())
    assert f"{path} {what}" in printed, printed
    assert "nothing written" in printed and "rover logs recover" not in printed
    assert not out.exists()


def test_a_cut_file_is_warned_of_once(
    recording: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(recording.read_bytes()[: recording.stat().st_size // 2])
    with caplog.at_level(logging.WARNING):
        (run,) = write_report([cut], tmp_path / "out", plots=False).runs
    assert run.metrics.truncated
    # the files given one by one are first looked at for a real-time pair, then read: one warning
    warnings = [r.getMessage() for r in caplog.records if r.getMessage().startswith(f"{cut} is cut short")]
    assert len(warnings) == 1, caplog.text


def test_a_cut_rover_file_with_its_truth_is_warned_of_once(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A real-time run's rover file is read twice (its drive first, then merged with the truth)."""
    _, rover, truth = write_pair(tmp_path / "run")
    cut = tmp_path / "rover-cut.mcap"
    cut.write_bytes(rover.read_bytes()[: rover.stat().st_size * 3 // 4])
    with caplog.at_level(logging.WARNING):
        (run,) = write_report([cut], tmp_path / "out", plots=False, truth=truth).runs
    assert run.truth_merged and run.metrics.truncated
    warnings = [r.getMessage() for r in caplog.records if r.getMessage().startswith(f"{cut} is cut short")]
    assert len(warnings) == 1, caplog.text


def test_the_markdown_says_where_the_plots_are(recording: Path, tmp_path: Path) -> None:
    plotted = write_report([recording], tmp_path / "plots")
    text = plotted.markdown.read_text(encoding="utf-8")
    assert text.startswith("# Trial report\n\n" + PLOTS_IN_HTML)
    assert (plotted.markdown.parent / "report.html").read_text(encoding="utf-8").count("<svg") == 4
    bare = write_report([recording], tmp_path / "tables", plots=False).markdown.read_text(encoding="utf-8")
    assert "report.html" in bare.splitlines()[2] and "--no-plots" in bare.splitlines()[2]
