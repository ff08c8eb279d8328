"""A lockstep trial on a swapped-in controller DBC: the rover and the simulated controllers both speak it.

The swapped profile (tests.firmware_bridge.swapped_dbc) has other controller ids, STATUS ``current`` in
centiamps and a little-endian STATUS_5: the trial must drive as it does on the shipped DBC, the recorded
frames must be in the swapped layout, and the recording must say which DBC it was.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import cantools
import pytest

from hil.scenario import Scenario, load_scenario
from hil.trial import TrialResult, run_trial
from logs import topics
from logs.reader import read_attachments, read_messages, read_metadata
from logs.settings import parse_toml
from navigator.config import load_rover_config, rover_config_from_table
from tests.firmware_bridge.swapped_dbc import SWAPPED_IDS, swapped_dbc_text

DATA = Path(__file__).resolve().parents[1] / "data"
SET_RPM, STATUS, STATUS_5 = 3, 9, 27  # VESC command ids, as the swapped profile keeps them
# The rover's path may differ only by what the finer current resolution could change (nothing it steers
# by reads the motor current today, so the two paths are in fact the same).
SAME_PATH_M = 0.01


@pytest.fixture(scope="module")
def short_scenario() -> Scenario:
    return dataclasses.replace(load_scenario(DATA / "small_rocky.toml"), duration_s=6.0)


@pytest.fixture(scope="module")
def dbc_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("site") / "profiles" / "other-firmware.dbc"
    path.parent.mkdir()
    path.write_text(swapped_dbc_text(), encoding="ascii")
    return path


@pytest.fixture(scope="module")
def swapped(
    short_scenario: Scenario, dbc_file: Path, tmp_path_factory: pytest.TempPathFactory
) -> TrialResult:
    config_path = dbc_file.parent.parent / "rover.toml"
    config_path.write_text(
        f'[vesc]\ncontroller_ids = {list(SWAPPED_IDS)}\ndbc = "profiles/{dbc_file.name}"\n', encoding="utf-8"
    )
    config = load_rover_config(config_path)
    return run_trial(short_scenario, config, tmp_path_factory.mktemp("swapped"))


@pytest.fixture(scope="module")
def shipped(short_scenario: Scenario, tmp_path_factory: pytest.TempPathFactory) -> TrialResult:
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    return run_trial(short_scenario, config, tmp_path_factory.mktemp("shipped"))


def _positions(result: TrialResult) -> list[tuple[float, float]]:
    poses = read_messages(result.mcap_path, topics=[topics.TRUTH_POSE])
    return [(p.message["pose"]["position"]["x"], p.message["pose"]["position"]["y"]) for p in poses]


def test_the_rover_drives_on_the_swapped_dbc_as_on_the_shipped_one(swapped, shipped):
    ours, reference = _positions(swapped), _positions(shipped)
    assert len(ours) == len(reference)
    driven = math.dist(reference[0], reference[-1])
    assert driven > 1.0, "the short trial should drive the rover somewhere"
    assert max(math.dist(a, b) for a, b in zip(ours, reference, strict=True)) < SAME_PATH_M


def _frames(result: TrialResult, direction: str) -> list[tuple[int, bytes]]:
    frames = read_messages(result.mcap_path, topics=[topics.CAN_FRAMES])
    return [
        (f.message["id"], bytes.fromhex(f.message["data"]))
        for f in frames
        if f.message["direction"] == direction
    ]


def test_the_recorded_frames_are_in_the_swapped_layout(swapped, dbc_file):
    by_id = {m.frame_id: m for m in cantools.database.load_file(dbc_file, database_format="dbc").messages}
    tx, rx = _frames(swapped, "tx"), _frames(swapped, "rx")
    assert {frame_id >> 8 for frame_id, _ in tx} == {SET_RPM}
    assert {frame_id & 0xFF for frame_id, _ in tx + rx} == set(SWAPPED_IDS)
    # STATUS_5 little-endian: the input voltage the simulated pack gives, read in that byte order.
    voltages = [int.from_bytes(data[4:6], "little") / 10 for i, data in rx if i >> 8 == STATUS_5]
    assert voltages and all(20.0 < v < 30.0 for v in voltages), voltages[:5]
    # STATUS current in centiamps: what the rover reported is what these frames carry at that scale.
    sent: dict[int, set[float]] = {cid: set() for cid in SWAPPED_IDS}
    for frame_id, data in rx:
        if frame_id >> 8 == STATUS:
            current = by_id[frame_id].decode(data)["current"]
            assert current == pytest.approx(int.from_bytes(data[4:6], "big", signed=True) / 100, abs=1e-9)
            sent[frame_id & 0xFF].add(current)
    reported = [
        (wheel["controller_id"], wheel["motor_current_a"])
        for status in read_messages(swapped.mcap_path, topics=[topics.WHEELS_STATUS])
        for wheel in status.message["wheels"]
        if wheel["motor_current_a"] != 0.0
    ]
    assert reported
    assert all(current in sent[cid] for cid, current in reported)
    # Finer than the shipped deciamps: some currents are not whole tenths of an ampere.
    assert any(abs(current * 10 - round(current * 10)) > 1e-6 for _, current in reported)


def test_the_recording_names_the_dbc_and_carries_the_file(swapped, dbc_file):
    config = read_metadata(swapped.mcap_path)["config"]
    assert config["vesc.dbc_path"] == str(dbc_file)
    assert config["vesc.controller_ids"] == str(list(SWAPPED_IDS))
    assert read_attachments(swapped.mcap_path)["vesc.dbc"] == dbc_file.read_bytes()


def test_a_trial_on_the_shipped_dbc_attaches_none(shipped):
    assert read_metadata(shipped.mcap_path)["config"]["vesc.dbc_path"] == "null"
    assert "vesc.dbc" not in read_attachments(shipped.mcap_path)
