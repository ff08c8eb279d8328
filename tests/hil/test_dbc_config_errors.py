"""``[vesc] dbc`` across processes: the peer hands it on to ``rover run``, which speaks it and records it;
a bad one stops every command."""

from __future__ import annotations

import logging
import os
import threading
from pathlib import Path

import pytest

from hil.campaign import campaign_config
from hil.peer_files import write_peer_files
from hil.scenario import load_scenario
from logs import topics
from logs.clock import MonotonicClock
from logs.reader import read_attachments, read_messages, read_metadata
from navigator.config import load_rover_config
from navigator.rover_process import run_rover
from rover_cli.main import main
from tests.firmware_bridge.swapped_dbc import SWAPPED_IDS, swapped_dbc_text, without_message
from tests.runtime.run_config import rover_run_config

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "small_rocky.toml"


def _config(folder: Path, dbc_text: str) -> Path:
    (folder / "profiles").mkdir(parents=True)
    (folder / "profiles" / "team.dbc").write_text(dbc_text, encoding="ascii")
    path = folder / "rover.toml"
    vesc = f'[vesc]\ncontroller_ids = {list(SWAPPED_IDS)}\ngear_ratio = 25.0\ndbc = "profiles/team.dbc"\n'
    path.write_text(vesc, encoding="utf-8")
    return path


def test_the_peers_rover_config_keeps_the_dbc_and_ids_readable_from_anywhere(tmp_path, monkeypatch):
    config = load_rover_config(_config(tmp_path / "site", swapped_dbc_text()))
    peer_dir = tmp_path / "peer"
    peer_dir.mkdir()
    written = write_peer_files(peer_dir, load_scenario(SCENARIO), config, mavlink_port=14550)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert load_rover_config(written).vesc == config.vesc
    # `rover hil soak` copies it into another folder, pointing only the map paths back at the peer's.
    copied = elsewhere / "rover-copy.toml"
    text = written.read_text(encoding="utf-8").replace('"map/', f'"{peer_dir}/map/')
    copied.write_text(text, encoding="utf-8")
    assert load_rover_config(copied).vesc.dbc_path == config.vesc.dbc_path


@pytest.mark.parametrize(
    "command",
    [
        ["run", "--config", "{config}", "--out", "{out}", "--no-telemetry"],
        ["hil", "trial", str(SCENARIO), "--config", "{config}", "--out", "{out}", "--no-telemetry"],
        ["hil", "peer", str(SCENARIO), "--config", "{config}", "--out", "{out}"],
    ],
    ids=["run", "hil-trial", "hil-peer"],
)
def test_an_unusable_dbc_stops_the_command_with_one_line_exit_2(tmp_path, capsys, caplog, command):
    config = _config(tmp_path, without_message(swapped_dbc_text(), "VESC_STATUS_5_C15"))
    out = tmp_path / "out"
    with caplog.at_level(logging.ERROR):
        code = main([part.format(config=config, out=out) for part in command])
    assert code == 2
    captured = capsys.readouterr()
    said = [line for line in (captured.out + captured.err).splitlines() if line.strip()]
    said += [record.getMessage() for record in caplog.records if record.levelno >= logging.ERROR]
    assert len(said) == 1, said
    assert (
        f"{config}: vesc.dbc: VESC DBC {tmp_path / 'profiles' / 'team.dbc'}: no message VESC_STATUS_5_C15"
        in said[0]
    )
    assert not out.exists()


def test_a_campaign_variant_reads_the_base_configs_dbc_from_the_base_configs_folder(tmp_path, monkeypatch):
    base = _config(tmp_path / "site", swapped_dbc_text())
    monkeypatch.chdir(tmp_path)  # the variant's label is no path: the folder must come from the base file
    variant = campaign_config(base, {"planner": {"cost_mode": "classical"}}, "rocky/classical/seed1")
    assert variant.vesc.dbc_path == tmp_path / "site" / "profiles" / "team.dbc"
    assert variant.source.endswith("+ overrides of rocky/classical/seed1")


def test_rover_run_speaks_the_dbc_and_its_recording_names_it(tmp_path):
    config_path = _config(tmp_path, swapped_dbc_text())
    vesc = config_path.read_text(encoding="utf-8")
    config_path.write_text(rover_run_config("dbctest", f"dbctest-{os.getpid()}") + vesc, encoding="utf-8")
    config = load_rover_config(config_path)
    out = tmp_path / "run"

    def broken_wait(timeout_s: float) -> None:  # ends the run at its first wait: the zeros still go out
        raise OSError("stop here")

    with pytest.raises(OSError, match="stop here"):
        run_rover(config, MonotonicClock(), out, stop=threading.Event(), wait=broken_wait, telemetry=False)
    recording = out / "rover.mcap"
    assert read_metadata(recording)["trial"]["vesc_dbc"] == str(tmp_path / "profiles" / "team.dbc")
    # and carries the file as read, as a lockstep trial's does: the path alone may not travel with it
    assert read_attachments(recording)["vesc.dbc"] == (tmp_path / "profiles" / "team.dbc").read_bytes()
    sent = {m.message["id"] for m in read_messages(recording, topics=[topics.CAN_FRAMES])}
    assert sent == {(3 << 8) | cid for cid in SWAPPED_IDS}  # SET_RPM zeros to the profile's controllers
