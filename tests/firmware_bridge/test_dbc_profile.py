"""``[vesc] dbc``: a team's own controller DBC, loaded and checked against what the codec needs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from firmware_bridge.errors import DbcProfileError
from firmware_bridge.frame_packer import FramePacker
from firmware_bridge.vesc import VescCodec, VescProfile
from firmware_bridge.vesc_dbc import generate_dbc, load_vesc_database
from logs.settings import ConfigError
from navigator.config import load_rover_config
from tests.firmware_bridge.swapped_dbc import SWAPPED_IDS, swapped_dbc_text, without_message

IDS_LINE = f"controller_ids = {list(SWAPPED_IDS)}"


def write(path: Path, text: str | bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="ascii")
    return path


def test_the_swapped_layout_is_what_the_codec_encodes_and_decodes(tmp_path):
    dbc = write(tmp_path / "other.dbc", swapped_dbc_text())
    profile = VescProfile(SWAPPED_IDS, 7, 20.0, 0.11, dbc_path=dbc)
    codec = VescCodec.for_profile(profile)
    status = codec.encode_in_range("STATUS", 12, {"erpm": 1500, "current": 12.34, "duty": 0.25})
    assert status.arbitration_id == (9 << 8) | 12
    assert bytes(status.data[4:6]) == (1234).to_bytes(2, "big", signed=True)  # centiamps, not deciamps
    status_5 = codec.encode_in_range("STATUS_5", 16, {"tacho": 2.0, "voltage_in": 24.5})
    assert bytes(status_5.data[:6]) == (12).to_bytes(4, "little") + (245).to_bytes(2, "little")
    decoded = codec.decode(status_5)
    assert decoded.values == pytest.approx({"tacho": 2.0, "voltage_in": 24.5})
    assert codec.decode(status).values["current"] == pytest.approx(12.34)
    # STATUS keeps a struct packer (at the new scale); the little-endian STATUS_5 has none: cantools does it.
    database = codec.database
    assert FramePacker.for_message(database.get_message_by_name("VESC_STATUS_C12")) is not None
    assert FramePacker.for_message(database.get_message_by_name("VESC_STATUS_5_C16")) is None


def _rename_first(text: str, old: str, new: str) -> str:
    edited, count = re.subn(re.escape(old), new, text, count=1)
    assert count == 1, old
    return edited


STATUS_DUTY = " SG_ duty : 55|16@0- (0.001,0)"
SET_RPM_C1 = "BO_ 2147484417 VESC_SET_RPM_C1: 4 COMPANION\n"
VOLTAGE_IN = ' SG_ voltage_in : 39|16@0- (0.1,0) [-3276.8|3276.7] "V" COMPANION\n'
SPARE = ' SG_ spare : 55|16@0- (1,0) [-32768|32767] "" COMPANION\n'  # STATUS_5's two reserved bytes


@pytest.mark.parametrize(
    ("ids", "edit", "expected"),
    [
        (
            SWAPPED_IDS,
            lambda text: without_message(text, "VESC_STATUS_4_C13"),
            r"no message VESC_STATUS_4_C13 \(the STATUS_4 frame of controller 13\)",
        ),
        (
            SWAPPED_IDS,
            lambda text: _rename_first(text, STATUS_DUTY, " SG_ duty_cycle : 55|16@0- (0.001,0)"),
            r"VESC_STATUS_C11 has no signal 'duty' \(the stack needs erpm, current, duty\)",
        ),
        (
            (1, 2, 3, 4, 5, 6),
            lambda text: _rename_first(text, SET_RPM_C1, SET_RPM_C1.replace("2147484417", str(0x301))),
            r"VESC_SET_RPM_C1 has the standard 11-bit id 0x301; VESC frames use 29-bit extended ids",
        ),
        (
            (1, 2, 3, 4, 5, 6),
            lambda text: _rename_first(text, VOLTAGE_IN, VOLTAGE_IN + SPARE),
            r"VESC_STATUS_5_C1 has a signal 'spare' the stack does not know; it encodes every signal",
        ),
        (
            SWAPPED_IDS,
            lambda text: text.replace("BO_ 2147487243 VESC_STATUS_2_C11", "BO_ 2147485963 VESC_STATUS_2_C11"),
            r"VESC_STATUS_2_C11 and VESC_STATUS_C11 share the id 0x0000090b",
        ),
    ],
    ids=["missing-message", "missing-signal", "standard-id", "unknown-signal", "shared-id"],
)
def test_a_dbc_the_codec_cannot_use_is_refused_naming_file_message_and_what(tmp_path, ids, edit, expected):
    dbc = write(
        tmp_path / "team.dbc", edit(swapped_dbc_text(ids) if ids == SWAPPED_IDS else generate_dbc(ids))
    )
    with pytest.raises(DbcProfileError, match=rf"^VESC DBC {re.escape(str(dbc))}: {expected}"):
        load_vesc_database(ids, dbc)


def test_the_dbc_must_cover_the_configured_ids(tmp_path):
    dbc = write(tmp_path / "team.dbc", swapped_dbc_text())
    with pytest.raises(
        DbcProfileError, match=r"no message VESC_SET_DUTY_C1 .*controller_ids \[1, 2, 3, 4, 5, 6\]"
    ):
        load_vesc_database((1, 2, 3, 4, 5, 6), dbc)


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (None, r"cannot read the file: Is a directory"),
        ("hello, I am not a DBC\nsecond line\n", r"not a DBC file cantools can load: .*hello"),
        (b"\x81\x00\xff\xfe binary", r"not a DBC file cantools can load"),
    ],
    ids=["directory", "text", "binary"],
)
def test_an_unreadable_or_non_dbc_file_is_refused_on_one_line(tmp_path, content, expected):
    path = tmp_path / "team.dbc"
    if content is None:
        path.mkdir()
    else:
        write(path, content)
    with pytest.raises(DbcProfileError, match=rf"^VESC DBC {re.escape(str(path))}: {expected}") as caught:
        load_vesc_database(SWAPPED_IDS, path)
    assert "\n" not in str(caught.value)


# --- the config key ------------------------------------------------------------------------------------


def config_with(folder: Path, vesc_lines: str) -> Path:
    return write(folder / "rover.toml", f"[vesc]\n{vesc_lines}\n")


def test_a_relative_dbc_path_is_read_from_the_config_folder(tmp_path, monkeypatch):
    write(tmp_path / "site" / "profiles" / "other.dbc", swapped_dbc_text())
    config_path = config_with(tmp_path / "site", f'{IDS_LINE}\ndbc = "profiles/other.dbc"')
    monkeypatch.chdir(tmp_path)  # not the config's folder: the path must not be read from here
    config = load_rover_config(Path("site") / "rover.toml")
    assert config.vesc.dbc_path == config_path.parent / "profiles" / "other.dbc"  # absolute
    assert VescCodec.for_profile(config.vesc).database.get_message_by_name("VESC_STATUS_C16")


def test_without_the_key_the_shipped_dbc_is_used(tmp_path):
    config = load_rover_config(config_with(tmp_path, "pole_pairs = 7"))
    assert config.vesc.dbc_path is None
    assert VescCodec.for_profile(config.vesc).database.get_message_by_name("VESC_STATUS_C1")


def test_a_dbc_path_written_from_the_current_directory_is_named_as_the_mix_up(tmp_path, monkeypatch):
    write(tmp_path / "profiles" / "other.dbc", swapped_dbc_text())
    monkeypatch.chdir(tmp_path)
    config_path = config_with(tmp_path / "site", f'{IDS_LINE}\ndbc = "profiles/other.dbc"')
    with pytest.raises(ConfigError) as caught:
        load_rover_config(config_path)
    assert caught.value.key == "vesc.dbc"
    assert "DBC file 'profiles/other.dbc' not found: a relative path is read from the folder of" in str(
        caught.value
    )
    assert "exists from the current directory" in str(caught.value)


def test_an_unusable_dbc_is_a_config_error_naming_the_key_and_the_file(tmp_path):
    write(tmp_path / "team.dbc", without_message(swapped_dbc_text(), "VESC_SET_RPM_C14"))
    config_path = config_with(tmp_path, f'{IDS_LINE}\ndbc = "team.dbc"')
    with pytest.raises(ConfigError) as caught:
        load_rover_config(config_path)
    assert caught.value.key == "vesc.dbc"
    said = str(caught.value)
    assert said.startswith(
        f"{config_path}: vesc.dbc: VESC DBC {tmp_path / 'team.dbc'}: no message VESC_SET_RPM_C14"
    )
    assert "\n" not in said


def test_a_misspelt_dbc_key_gets_the_typo_suggestion(tmp_path):
    with pytest.raises(ConfigError, match=r"vesc\.dcb: unknown key \(did you mean 'dbc'\?"):
        load_rover_config(config_with(tmp_path, 'dcb = "team.dbc"'))


def test_a_dbc_is_parsed_once_per_process_until_the_file_changes(tmp_path):
    # Each lockstep trial used to parse the DBC again (~9 ms), and a team's file twice at start-up.
    assert load_vesc_database() is load_vesc_database()
    dbc = write(tmp_path / "team.dbc", swapped_dbc_text())
    first = load_vesc_database(SWAPPED_IDS, dbc)
    assert load_vesc_database(SWAPPED_IDS, dbc) is first
    # An edited file (here: STATUS_5 gone) is read again, and refused as any bad file is.
    write(dbc, without_message(swapped_dbc_text(), "VESC_STATUS_5_C15"))
    with pytest.raises(DbcProfileError, match="no message VESC_STATUS_5_C15"):
        load_vesc_database(SWAPPED_IDS, dbc)
    dbc.unlink()
    with pytest.raises(DbcProfileError, match="cannot read the file"):
        load_vesc_database(SWAPPED_IDS, dbc)
