"""``rover hil peer`` refuses a CAN bus that cannot reach ``rover run`` in another process."""

from __future__ import annotations

from pathlib import Path

import pytest

from rover_cli.main import main

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "small_rocky.toml"


def test_the_peer_refuses_the_in_process_virtual_bus_and_says_what_to_use(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # `rover hil peer SCENARIO --out OUT` with the built-in config had opened python-can's virtual bus:
    # the peer ran, wrote a rover-hil.toml naming it, and `rover run` with that file heard no controller.
    out = tmp_path / "peer"
    code = main(["hil", "peer", str(SCENARIO), "--out", str(out), "--duration", "0.5"])
    assert code == 2
    said = " ".join(capsys.readouterr().err.split())
    assert "virtual bus reaches only this process" in said
    assert "--can-interface udp_multicast" in said and "scripts/in-private-netns" in said
    assert not out.exists()
