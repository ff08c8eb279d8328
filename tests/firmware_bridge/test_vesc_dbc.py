from pathlib import Path

import cantools
import pytest

import firmware_bridge
from firmware_bridge.errors import BridgeSetupError
from firmware_bridge.vesc import VescProfile
from firmware_bridge.vesc_dbc import DEFAULT_CONTROLLER_IDS, generate_dbc, load_vesc_database
from logs.settings import ConfigError, parse_toml

SHIPPED = Path(firmware_bridge.__file__).parent / "vesc_6wheel.dbc"


def test_shipped_dbc_equals_generated_for_default_ids():
    assert SHIPPED.read_text(encoding="ascii") == generate_dbc(list(DEFAULT_CONTROLLER_IDS))


def test_default_database_has_every_message_with_extended_ids():
    db = load_vesc_database()
    rpm = db.get_message_by_name("VESC_SET_RPM_C1")
    assert rpm.frame_id == (3 << 8) | 1
    assert rpm.is_extended_frame
    assert rpm.length == 4
    status5 = db.get_message_by_name("VESC_STATUS_5_C6")
    assert status5.frame_id == (27 << 8) | 6
    signal = status5.get_signal_by_name("tacho")
    assert signal.byte_order == "big_endian" and signal.is_signed
    assert signal.scale == pytest.approx(1 / 6)
    assert db.get_message_by_name("VESC_STATUS_4_C3").get_signal_by_name("current_in").unit == "A"
    assert len(db.messages) == 6 * 9


def test_other_ids_generate_their_own_database():
    db = load_vesc_database([10, 11, 12, 13, 14, 254])
    assert db.get_message_by_name("VESC_STATUS_C254").frame_id == (9 << 8) | 254
    with pytest.raises(KeyError):
        db.get_message_by_name("VESC_STATUS_C1")
    # and the text is plain DBC cantools reads on its own
    assert cantools.database.load_string(generate_dbc([7]), database_format="dbc").messages


@pytest.mark.parametrize("ids", [[], [1, 1], [256], [-1], [1, 2, 3, 4, 5, 255]])
def test_bad_controller_ids_are_setup_errors(ids):
    with pytest.raises(BridgeSetupError, match="controller id"):
        generate_dbc(ids)


def test_the_broadcast_id_is_refused_in_the_config_saying_why():
    # VESC firmware obeys a command to 255 whatever its own id: that wheel's commands would drive all six.
    text = "[vesc]\ncontroller_ids = [1, 2, 3, 4, 5, 255]"
    with pytest.raises(
        ConfigError, match=r"rover\.toml: vesc\.controller_ids: .*255 is the VESC broadcast id"
    ):
        VescProfile.from_table(parse_toml(text, "rover.toml").table("vesc"), wheel_radius_m=0.1)
    with pytest.raises(BridgeSetupError, match="broadcast"):
        VescProfile((1, 2, 3, 4, 5, 255), pole_pairs=7, gear_ratio=20.0, wheel_radius_m=0.1)
    assert VescProfile.from_table(
        parse_toml("[vesc]\ncontroller_ids = [0, 2, 3, 4, 5, 254]", "rover.toml").table("vesc"),
        wheel_radius_m=0.1,
    ).controller_ids == (0, 2, 3, 4, 5, 254)
