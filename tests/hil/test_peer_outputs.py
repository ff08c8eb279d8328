"""``rover hil peer`` refuses output paths it cannot use, before it runs, and never overwrites a recording."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from rover_cli.main import main
from tests.system.realtime_rig import fresh_multicast_group, needs_netns

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "small_rocky.toml"


def _peer(capsys: pytest.CaptureFixture[str], *options: str) -> tuple[int, str]:
    code = main(
        [
            "hil", "peer", str(SCENARIO), "--can-interface", "udp_multicast",
            "--can-channel", fresh_multicast_group(), "--duration", "0.5", *options,
        ]
    )  # fmt: skip
    return code, " ".join(capsys.readouterr().err.split())


@needs_netns
def test_an_out_that_is_a_file_is_bad_input_not_a_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # `rover hil peer ... --out FILE` had raised FileExistsError from inside run_peer, after the wires opened.
    a_file = tmp_path / "peer"
    a_file.write_text("not a folder", encoding="utf-8")
    code, said = _peer(capsys, "--out", str(a_file))
    assert code == 2
    assert f"--out {a_file}: exists and is not a directory" in said
    assert a_file.read_text(encoding="utf-8") == "not a folder"


@needs_netns
def test_an_earlier_runs_truth_is_left_as_it_is(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # The peer had opened truth.mcap for writing: run again into the same --out (as docs/hil.md's example
    # does), it emptied the earlier run's ground truth, which that run's rover.mcap is reported against.
    out = tmp_path / "peer"
    out.mkdir()
    earlier = b"an earlier run's ground truth"
    (out / "truth.mcap").write_bytes(earlier)
    code, said = _peer(capsys, "--out", str(out))
    assert code == 2
    assert f"{out / 'truth.mcap'} already exists" in said and "--out" in said
    assert (out / "truth.mcap").read_bytes() == earlier
    assert not (out / "rover-hil.toml").exists()


def _a_folder(tmp_path: Path) -> Path:
    folder = tmp_path / "a-folder"
    folder.mkdir()
    return folder


def _under_a_file(tmp_path: Path) -> Path:
    a_file = tmp_path / "a-file"
    a_file.write_text("", encoding="utf-8")
    return a_file / "port"


@needs_netns
@pytest.mark.parametrize("option", ["--port-file", "--status-file"])
@pytest.mark.parametrize(
    ("where", "complaint"),
    [(_a_folder, "is a directory"), (_under_a_file, "cannot create its folder")],
)
def test_a_port_or_status_file_the_peer_cannot_write_is_bad_input(
    option: str,
    where: Callable[[Path], Path],
    complaint: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    # --port-file DIR had raised IsADirectoryError once the peer was ready, after writing rover-hil.toml.
    path = where(tmp_path)
    code, said = _peer(capsys, "--out", str(tmp_path / "peer"), option, str(path))
    assert code == 2
    assert f"{option} {path}: {complaint}" in said
    assert not (tmp_path / "peer" / "truth.mcap").exists()
