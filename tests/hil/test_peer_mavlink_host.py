"""``rover hil peer --mavlink udpin:HOST:PORT``: the rover is told to dial the host the peer listens on."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from rover_cli.main import main
from tests.system.realtime_rig import fresh_multicast_group, needs_netns

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "small_rocky.toml"


@needs_netns
def test_the_rover_config_and_the_printed_line_name_the_loopback_address_the_peer_listens_on(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # With --mavlink udpin:127.0.0.5:0 the peer listened there but wrote udpout:127.0.0.1:PORT into
    # rover-hil.toml (and printed it): `rover run` with that file never heard the autopilot.
    out = tmp_path / "peer"
    code = main(
        [
            "hil", "peer", str(SCENARIO), "--can-interface", "udp_multicast",
            "--can-channel", fresh_multicast_group(), "--mavlink", "udpin:127.0.0.5:0",
            "--duration", "0.5", "--out", str(out), "--port-file", str(out / "port"),
        ]
    )  # fmt: skip
    printed = capsys.readouterr()
    assert code == 0, f"exit {code}; stdout: {printed.out!r}; stderr: {printed.err!r}"
    port = int((out / "port").read_text(encoding="utf-8"))
    written = tomllib.loads((out / "rover-hil.toml").read_text(encoding="utf-8"))
    assert written["mavlink"]["connection"] == f"udpout:127.0.0.5:{port}"
    assert f"mavlink: udpout:127.0.0.5:{port}" in printed.out
