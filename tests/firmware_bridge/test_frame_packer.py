"""The hot-path frame packer gives cantools' bytes and values, and declines layouts it cannot express."""

from __future__ import annotations

import random

import can
import cantools
import pytest
from cantools.database.conversion import LinearConversion

from firmware_bridge.errors import BridgeOperationError, BridgeSetupError, FrameError
from firmware_bridge.frame_packer import FramePacker
from firmware_bridge.vesc_dbc import VESC_MESSAGES, message_name
from tests.firmware_bridge.virtual_can import make_codec


def _random_in_range(rng: random.Random, signal: cantools.database.can.Signal) -> float:
    """A physical value whose raw value fits the field, sometimes exactly on its edges."""
    bits = signal.length
    low, high = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signal.is_signed else (0, (1 << bits) - 1)
    raw = rng.choice([low, high, 0, -1 if signal.is_signed else 1, rng.randint(low, high)])
    value = raw * signal.conversion.scale + signal.conversion.offset
    # Off the raw grid by up to 0.49 steps (rounding is cantools', to the last bit), kept inside the field.
    nudge = rng.uniform(-0.49, 0.49) * signal.conversion.scale
    return float(value + nudge) if low < raw < high else float(value)


@pytest.mark.parametrize("seed", range(3))
def test_packer_bytes_equal_cantools_bytes_for_random_values(seed: int) -> None:
    rng = random.Random(seed)
    codec = make_codec()
    for spec in VESC_MESSAGES:
        message = codec.database.get_message_by_name(message_name(spec.kind, 1))
        packer = FramePacker.for_message(message)
        assert packer is not None, f"{message.name} should have a plain layout"
        for _ in range(300):
            values = {signal.name: _random_in_range(rng, signal) for signal in message.signals}
            expected = message.encode(values, strict=False)
            assert packer.pack(values) == expected, values
            frame = codec.encode_in_range(spec.kind, 1, values)
            assert bytes(frame.data) == expected and frame.dlc == message.length


@pytest.mark.parametrize("seed", range(3))
def test_decode_gives_cantools_numbers_for_random_payloads(seed: int) -> None:
    rng = random.Random(seed)
    codec = make_codec()
    for spec in VESC_MESSAGES:
        message = codec.database.get_message_by_name(message_name(spec.kind, 4))
        for _ in range(300):
            data = bytes(rng.randrange(256) for _ in range(message.length))
            msg = can.Message(arbitration_id=message.frame_id, is_extended_id=True, data=data)
            decoded = message.decode(data, decode_choices=False)
            assert isinstance(decoded, dict)
            expected = {name: float(value) for name, value in decoded.items()}  # type: ignore[arg-type]
            frame = codec.decode(msg)
            assert (frame.kind, frame.controller_id, frame.values) == (spec.kind, 4, expected)


def test_out_of_range_values_take_the_cantools_path() -> None:
    codec = make_codec()
    message = codec.database.get_message_by_name(message_name("STATUS", 2))
    packer = FramePacker.for_message(message)
    assert packer is not None
    values = {"erpm": 3e9, "current": 1.0, "duty": 0.5}  # erpm beyond int32
    with pytest.raises(OverflowError):  # what cantools (bitstruct) does with it ...
        message.encode(values, strict=False)
    with pytest.raises(OverflowError):  # ... the packer does too
        packer.pack(values)


def test_set_rpm_goes_through_the_packer_with_the_same_bytes() -> None:
    codec = make_codec()
    message = codec.database.get_message_by_name(message_name("SET_RPM", 5))
    for erpm in (0, 1, -1, 1234.5, -98765.4, 2**31 - 1, -(2**31), 1e12, -1e12):
        expected = message.encode({"erpm": max(-(2**31), min(2**31 - 1, round(erpm)))})
        assert bytes(codec.encode_set_rpm(5, erpm).data) == expected


def test_packer_decode_keeps_the_strict_checks() -> None:
    codec = make_codec()
    status_id = (9 << 8) | 1
    with pytest.raises(FrameError) as wrong_dlc:
        codec.decode(can.Message(arbitration_id=status_id, is_extended_id=True, data=b"\x00" * 4))
    assert wrong_dlc.value.reason == "wrong_dlc"
    with pytest.raises(FrameError) as unknown:
        codec.decode(can.Message(arbitration_id=(9 << 8) | 99, is_extended_id=True, data=b"\x00" * 8))
    assert unknown.value.reason == "unknown_id"
    with pytest.raises(FrameError) as standard:
        codec.decode(can.Message(arbitration_id=0x101, is_extended_id=False, data=b"\x00" * 8))
    assert standard.value.reason == "not_extended"


DBC_WITH_ODD_LAYOUTS = """VERSION ""

NS_ :

BS_:

BU_: A B

BO_ 2147483905 LITTLE: 8 A
 SG_ value : 0|32@1- (1,0) [0|0] "" B

BO_ 2147483906 UNALIGNED: 8 A
 SG_ value : 3|12@0- (1,0) [0|0] "" B

BO_ 2147483907 FLOATING: 8 A
 SG_ value : 7|32@0- (1,0) [0|0] "" B

BO_ 2147483908 PLAIN: 8 A
 SG_ first : 7|16@0+ (0.5,-3) [0|0] "" B
 SG_ second : 39|8@0- (2,0) [0|0] "" B

SIG_VALTYPE_ 2147483907 value : 1;
"""


class _ShiftedConversion(LinearConversion):
    """A conversion whose scaling is not raw * scale + offset: unpack's arithmetic would be wrong for it."""

    def raw_to_scaled(self, raw_value: float, decode_choices: bool = True) -> float:
        return raw_value * self.scale + self.offset + 1.0


def test_conversions_other_than_cantools_plain_classes_are_declined() -> None:
    database = cantools.database.load_string(DBC_WITH_ODD_LAYOUTS, database_format="dbc")
    assert isinstance(database, cantools.database.can.Database)
    plain = database.get_message_by_name("PLAIN")
    assert FramePacker.for_message(plain) is not None
    first = plain.get_signal_by_name("first")
    first.conversion = _ShiftedConversion(
        scale=first.conversion.scale, offset=first.conversion.offset, is_float=False
    )
    assert FramePacker.for_message(plain) is None


def test_layouts_struct_cannot_express_are_declined() -> None:
    database = cantools.database.load_string(DBC_WITH_ODD_LAYOUTS, database_format="dbc")
    assert isinstance(database, cantools.database.can.Database)
    for name in ("LITTLE", "UNALIGNED", "FLOATING"):
        assert FramePacker.for_message(database.get_message_by_name(name)) is None, name
    plain = database.get_message_by_name("PLAIN")
    packer = FramePacker.for_message(plain)
    assert packer is not None
    rng = random.Random(7)
    for _ in range(200):
        values = {signal.name: _random_in_range(rng, signal) for signal in plain.signals}
        assert packer.pack(values) == plain.encode(values, strict=False)
        # An offset and a fractional scale: the inlined conversion of ``packing`` rounds as cantools does.
        names = ["second", "first"]
        assert packer.packing(names, {})([values[n] for n in names]) == plain.encode(values, strict=False)
        data = bytes(rng.randrange(256) for _ in range(8))
        decoded = plain.decode(data, decode_choices=False)
        assert isinstance(decoded, dict)
        assert all(isinstance(value, int | float) for value in decoded.values())
        assert packer.unpack(data) == {key: float(value) for key, value in decoded.items()}  # type: ignore[arg-type]


@pytest.mark.parametrize("seed", range(2))
def test_field_decoders_give_decode_numbers_and_leave_what_decode_refuses_to_it(seed: int) -> None:
    rng = random.Random(seed)
    codec = make_codec()
    shapes = [(message, count) for message in VESC_MESSAGES for count in range(1, len(message.signals) + 1)]
    for spec, count in shapes:
        names = [signal.name for signal in spec.signals]
        rng.shuffle(names)
        names = names[:count]  # one field, two, ... all, in any order (the readers written out and looped)
        decoders = codec.field_decoders(spec.kind, names)
        assert len(decoders) == 6
        for frame_id, decoder in decoders.items():
            assert decoder.kind == spec.kind
            for _ in range(50):
                data = bytes(rng.randrange(256) for _ in range(spec.length))
                msg = can.Message(arbitration_id=frame_id, is_extended_id=True, data=data)
                frame = codec.decode(msg)
                values = decoder.values(msg)
                assert values == [frame.values[name] for name in names]
                assert values is not None and all(type(value) is float for value in values)  # as decode's
                assert decoder.controller_id == frame.controller_id
                assert decoder.length == len(data)
            full = bytes(spec.length)
            refused = [
                can.Message(arbitration_id=frame_id, is_extended_id=False, data=full),
                can.Message(
                    arbitration_id=frame_id, is_extended_id=True, is_remote_frame=True, dlc=spec.length
                ),
                can.Message(arbitration_id=frame_id, is_extended_id=True, data=full[:-1]),
                can.Message(arbitration_id=frame_id, is_extended_id=True, data=full + b"\x00"),
                can.Message(arbitration_id=frame_id, is_extended_id=True, data=full, dlc=spec.length - 1),
            ]
            for msg in refused:
                assert decoder.values(msg) is None
                with pytest.raises(FrameError):
                    codec.decode(msg)


def test_a_field_decoder_of_a_signal_the_message_lacks_is_refused_at_setup() -> None:
    with pytest.raises(BridgeSetupError, match="no signal volts"):
        make_codec().field_decoders("STATUS", ("erpm", "volts"))


@pytest.mark.parametrize("packed", [True, False])
def test_field_encoders_give_the_frame_encoders_bytes(packed: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """From values in the sender's order, some signals held fixed, a field encoder's frame is the frame
    ``FrameEncoder.encode`` makes of the same values: by the packer, or by cantools without one."""
    if not packed:
        monkeypatch.setattr("firmware_bridge.vesc.FramePacker.for_message", lambda message: None)
    rng = random.Random(5)
    codec = make_codec()
    for spec in VESC_MESSAGES:
        message = codec.database.get_message_by_name(message_name(spec.kind, 3))
        for _ in range(100):
            values = {signal.name: _random_in_range(rng, signal) for signal in message.signals}
            names = list(values)
            rng.shuffle(names)
            held = names[rng.randint(1, len(names)) :]  # the first one at least is a value
            varying = [name for name in names if name not in held]
            fields = codec.encoder(spec.kind, 3).fields(varying, {name: values[name] for name in held})
            frame = fields.encode([values[name] for name in varying])
            expected = codec.encoder(spec.kind, 3).encode(values)
            assert bytes(frame.data) == bytes(expected.data), values
            assert (frame.arbitration_id, frame.is_extended_id, frame.dlc) == (
                expected.arbitration_id,
                True,
                expected.dlc,
            )


def test_a_field_encoder_must_name_every_signal_once() -> None:
    encoder = make_codec().encoder("STATUS", 1)
    with pytest.raises(BridgeSetupError, match="once"):
        encoder.fields(("erpm", "current"))  # duty missing
    with pytest.raises(BridgeSetupError, match="once"):
        encoder.fields(("erpm", "current", "duty"), {"duty": 0.0})
    with pytest.raises(BridgeOperationError, match="cannot encode VESC_STATUS_C1"):
        encoder.fields(("erpm", "current", "duty")).encode((1.0, 2.0))  # a value short


@pytest.mark.parametrize("seed", range(3))
def test_packing_of_every_signal_in_struct_order_gives_cantools_bytes(seed: int) -> None:
    """Every signal given, in the struct's order, none held: ``packing`` writes the conversions out (STATUS,
    STATUS_5, SET_RPM: what the controllers and the link send); the bytes are still cantools', ints and
    floats alike, and a value beyond its field goes to cantools, which raises what it always raised."""
    rng = random.Random(seed)
    codec = make_codec()
    written_out = 0
    for spec in VESC_MESSAGES:
        message = codec.database.get_message_by_name(message_name(spec.kind, 2))
        packer = FramePacker.for_message(message)
        assert packer is not None
        names = [signal.name for signal in sorted(message.signals, key=lambda signal: signal.start // 8)]
        pack = packer.packing(names, {})
        written_out += pack.__name__ != "pack_values"  # the loop's name: this shape is written out
        for _ in range(300):
            values = {signal.name: _random_in_range(rng, signal) for signal in message.signals}
            if rng.random() < 0.5:  # whole numbers as ints (the controllers' rounded ERPM)
                values = {name: _int_if_whole(value) for name, value in values.items()}
            assert pack([values[name] for name in names]) == message.encode(values, strict=False), values
    assert written_out >= 3
    status = codec.database.get_message_by_name(message_name("STATUS", 2))
    pack_status = FramePacker.for_message(status).packing(("erpm", "current", "duty"), {})  # type: ignore[union-attr]
    for erpm in (0, -1, 2**31 - 1, -(2**31), 2**53 + 1):
        values = {"erpm": erpm, "current": -12.3, "duty": 0.25}
        try:
            expected: bytes | type[Exception] = status.encode(values, strict=False)
        except Exception as err:  # beyond the field: cantools' own error
            expected = type(err)
        if isinstance(expected, bytes):
            assert pack_status([erpm, -12.3, 0.25]) == expected
        else:
            with pytest.raises(expected):
                pack_status([erpm, -12.3, 0.25])


def _int_if_whole(value: float) -> float:
    return round(value) if value == round(value) else value
