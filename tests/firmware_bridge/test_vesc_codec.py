import math

import can
import pytest

from firmware_bridge.errors import BridgeOperationError, BridgeSetupError, FrameError
from firmware_bridge.vesc import VescProfile, data_frame
from logs.settings import ConfigError, parse_toml
from tests.firmware_bridge.virtual_can import TEST_PROFILE, make_codec


def frame(can_id: int, hex_data: str, *, extended: bool = True) -> can.Message:
    data = bytes.fromhex(hex_data)
    return can.Message(arbitration_id=can_id, is_extended_id=extended, data=data, dlc=len(data))


def test_hand_built_status_frame_decodes_to_documented_values():
    # STATUS (9) from controller 2: ERPM 1234, motor current 12.3 A (x10), duty 0.5 (x1000)
    decoded = make_codec().decode(frame((9 << 8) | 2, "00 00 04 d2 00 7b 01 f4"))
    assert decoded.kind == "STATUS"
    assert decoded.controller_id == 2
    assert decoded.values == pytest.approx({"erpm": 1234.0, "current": 12.3, "duty": 0.5})


def test_negative_values_and_slow_status_frames():
    codec = make_codec()
    status = codec.decode(frame((9 << 8) | 1, "ff ff fb 2e ff 85 fe 0c"))
    assert status.values == pytest.approx({"erpm": -1234.0, "current": -12.3, "duty": -0.5})
    # STATUS_5: tachometer 600 steps = 100 erev, input voltage 24.5 V
    status5 = codec.decode(frame((27 << 8) | 4, "00 00 02 58 00 f5 00 00"))
    assert status5.values == pytest.approx({"tacho": 100.0, "voltage_in": 24.5})
    # STATUS_4: FET 30.1 C, motor 40.0 C, input current 5.5 A, pid pos 10 deg (x50)
    status4 = codec.decode(frame((16 << 8) | 6, "01 2d 01 90 00 37 01 f4"))
    assert status4.values == pytest.approx(
        {"temp_fet": 30.1, "temp_motor": 40.0, "current_in": 5.5, "pid_pos": 10.0}
    )


def test_set_rpm_encoding_matches_hand_written_bytes():
    codec = make_codec()
    msg = codec.encode_set_rpm(3, 1234.4)
    assert msg.arbitration_id == (3 << 8) | 3
    assert msg.is_extended_id
    assert msg.dlc == 4
    assert bytes(msg.data) == bytes.fromhex("000004d2")
    assert bytes(codec.encode_set_rpm(3, -1234).data) == bytes.fromhex("fffffb2e")
    assert bytes(codec.encode("SET_RPM", 3, erpm=1234).data) == bytes.fromhex("000004d2")
    # clamped to int32 rather than overflowing
    assert bytes(codec.encode_set_rpm(1, 1e12).data) == bytes.fromhex("7fffffff")


def test_data_frame_is_the_constructors_message_slot_for_slot():
    """data_frame writes the message's slots itself (hot path): every slot python-can's Message has,
    named by the class (so a python-can that adds one fails here), holds what its constructor gives."""
    for frame_id, data in ((0x903, b"\x00\x00\x04\xd2"), (0x1FFFFFFF, bytes(range(8))), (0, b"")):
        fast = data_frame(frame_id, len(data), data)
        slow = can.Message(arbitration_id=frame_id, is_extended_id=True, data=data, dlc=len(data))
        slots = [name for name in can.Message.__slots__ if name != "__weakref__"]
        assert {name: getattr(fast, name) for name in slots} == {name: getattr(slow, name) for name in slots}
        assert type(fast.data) is bytearray
        assert fast.equals(slow)


def test_encode_round_trips_through_decode():
    codec = make_codec()
    msg = codec.encode("STATUS", 5, erpm=-4000, current=-3.2, duty=0.25)
    assert msg.dlc == 8
    assert codec.decode(msg).values == pytest.approx({"erpm": -4000, "current": -3.2, "duty": 0.25})


def test_encode_rejects_bad_requests():
    codec = make_codec()
    with pytest.raises(BridgeOperationError, match="controller 9"):
        codec.encode("SET_RPM", 9, erpm=1)
    with pytest.raises(BridgeOperationError, match="VESC_STATUS_C1"):
        codec.encode("STATUS", 1, erpm=1)  # missing signals
    with pytest.raises(BridgeOperationError, match="finite"):
        codec.encode_set_rpm(1, math.nan)


def test_encoders_refuse_what_encode_refuses():
    """The hot-path encoders name an unknown kind or controller, and a frame missing a field, the same way."""
    codec = make_codec()
    with pytest.raises(BridgeOperationError, match="controller 9"):
        codec.encoder("SET_RPM", 9)
    with pytest.raises(BridgeOperationError, match=r"'NOPE'.*kinds"):
        codec.encode_in_range("NOPE", 1, {"erpm": 1})
    with pytest.raises(BridgeOperationError, match="VESC_STATUS_C1"):
        codec.encoder("STATUS", 1).encode({"erpm": 1})  # missing signals
    status = codec.encoder("STATUS", 2).encode({"erpm": -4000, "current": -3.2, "duty": 0.25})
    assert status.arbitration_id == (9 << 8) | 2 and status.is_extended_id and status.dlc == 8
    assert codec.decode(status).values == pytest.approx({"erpm": -4000, "current": -3.2, "duty": 0.25})


@pytest.mark.parametrize(
    ("msg", "reason", "text"),
    [
        (frame((9 << 8) | 42, "0000000000000000"), "unknown_id", "0x0000092a"),
        (frame(0x123, "0000000000000000", extended=False), "not_extended", "11-bit"),
        (frame((9 << 8) | 1, "000004d2007b"), "wrong_dlc", "expected 8"),
        # A request for a status frame (RTR, dlc 8, no data): it was said to have "0 data bytes (dlc 8),
        # expected 8", a length that was right.
        (
            can.Message(arbitration_id=(9 << 8) | 2, is_extended_id=True, is_remote_frame=True, dlc=8),
            "wrong_dlc",
            r"^VESC_STATUS_C2 \(id 0x00000902\) came as a remote frame \(a request for data, dlc 8\), "
            "not the data frame a controller sends",
        ),
    ],
)
def test_decode_is_strict(msg, reason, text):
    with pytest.raises(FrameError, match=text) as caught:
        make_codec().decode(msg)
    assert caught.value.reason == reason
    assert caught.value.frame_id == msg.arbitration_id


def test_profile_converts_speed_and_erpm():
    # 1 m/s on a 0.15 m wheel: 63.66 wheel RPM, x20 gear = 1273.2 motor RPM, x7 pole pairs = 8912.7 ERPM
    assert TEST_PROFILE.erpm_from_speed(1.0) == pytest.approx(60 / (2 * math.pi * 0.15) * 20 * 7)
    assert TEST_PROFILE.speed_from_erpm(TEST_PROFILE.erpm_from_speed(-0.7)) == pytest.approx(-0.7)


def test_profile_from_table_with_defaults_and_errors():
    table = parse_toml("controller_ids = [6, 5, 4, 3, 2, 1]", "rover.toml")
    profile = VescProfile.from_table(table, wheel_radius_m=0.2)
    assert profile == VescProfile((6, 5, 4, 3, 2, 1), 7, 20.0, 0.2)
    with pytest.raises(ConfigError, match="controller_ids"):
        VescProfile.from_table(parse_toml("controller_ids = [1, 1, 2, 3, 4, 5]", "r.toml"), 0.2)
    with pytest.raises(ConfigError, match="gear_ration"):
        VescProfile.from_table(parse_toml("gear_ration = 3.0", "r.toml"), 0.2)
    with pytest.raises(BridgeSetupError, match="wheel_radius_m"):
        VescProfile((1, 2, 3, 4, 5, 6), 7, 20.0, 0.0)
