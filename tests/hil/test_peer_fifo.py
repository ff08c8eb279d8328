"""``rover hil peer --fifo N`` runs the simulated rover at SCHED_FIFO, as the hardware it stands for."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rover_cli.main import build_parser
from tests.system.realtime_rig import fresh_multicast_group, needs_netns

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "tests" / "data" / "small_rocky.toml"


@pytest.mark.realtime
@needs_netns
def test_the_peer_runs_at_the_priority_asked_or_says_why_not(tmp_path: Path) -> None:
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "rover_cli.main",
            "hil",
            "peer",
            str(SCENARIO),
            "--can-interface",
            "udp_multicast",
            "--can-channel",
            fresh_multicast_group(),
            "--duration",
            "1",
            "--fifo",
            "10",
            "--out",
            str(tmp_path / "peer"),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    said = " ".join(done.stderr.split())
    assert (
        "scheduling: SCHED_FIFO 10, as timer-driven hardware" in said
        or "scheduling: normal scheduling (SCHED_FIFO 10 refused:" in said
    )
    assert (tmp_path / "peer" / "truth.mcap").exists()  # it ran its second and recorded it


@pytest.mark.parametrize("value", ["100", "-1", "fast"])
def test_a_priority_outside_0_to_99_is_refused(value: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        build_parser("hil").parse_args(["hil", "peer", str(SCENARIO), "--fifo", value])
    assert exit_info.value.code == 2
    assert "--fifo" in capsys.readouterr().err
