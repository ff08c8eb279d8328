"""VESC motor controllers: the wheel profile (ids, gearing) and a strict frame codec over the DBC."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import can
import cantools
import cantools.database

from firmware_bridge.errors import BridgeOperationError, BridgeSetupError, DbcProfileError, FrameError
from firmware_bridge.frame_packer import FramePacker
from firmware_bridge.vesc_dbc import (
    BROADCAST_NOTE,
    DEFAULT_CONTROLLER_IDS,
    MAX_CONTROLLER_ID,
    VESC_MESSAGES,
    load_vesc_database,
    message_name,
)
from logs.settings import Table

WHEEL_COUNT = 6
_INT32_MIN = -(1 << 31)
_INT32_MAX = (1 << 31) - 1
_SECONDS_PER_MINUTE = 60.0


@dataclass(frozen=True)
class VescProfile:
    """How six VESCs map to the wheels: ids in wheel order (LF, LM, LR, RF, RM, RR) and the drivetrain.

    ERPM = motor mechanical RPM x pole pairs; motor RPM = wheel RPM x gear ratio;
    wheel RPM = surface speed / (2 pi r) x 60.
    ``dbc_path``: the team's own DBC file the controllers' protocol is read from (``[vesc] dbc``); None:
    the shipped one (generated for ids other than 1..6).
    """

    controller_ids: tuple[int, ...]
    pole_pairs: int
    gear_ratio: float
    wheel_radius_m: float
    dbc_path: Path | None = None

    def __post_init__(self) -> None:
        ids = self.controller_ids
        if len(ids) != WHEEL_COUNT or len(set(ids)) != WHEEL_COUNT:
            raise BridgeSetupError(
                f"need {WHEEL_COUNT} distinct VESC controller ids in wheel order, got {ids}"
            )
        if not all(
            isinstance(c, int) and not isinstance(c, bool) and 0 <= c <= MAX_CONTROLLER_ID for c in ids
        ):
            raise BridgeSetupError(
                f"VESC controller ids must be integers 0..{MAX_CONTROLLER_ID}, got {ids} ({BROADCAST_NOTE})"
            )
        if self.pole_pairs < 1:
            raise BridgeSetupError(f"pole_pairs must be >= 1, got {self.pole_pairs}")
        if not (math.isfinite(self.gear_ratio) and self.gear_ratio > 0):
            raise BridgeSetupError(f"gear_ratio must be a positive number, got {self.gear_ratio}")
        if not (math.isfinite(self.wheel_radius_m) and self.wheel_radius_m > 0):
            raise BridgeSetupError(f"wheel_radius_m must be a positive number, got {self.wheel_radius_m}")

    @functools.cached_property
    def erpm_per_mps(self) -> float:
        # Computed once per profile: the link and the simulated controllers convert with it every frame and
        # step, and the profile is frozen. (cached_property writes the instance's dict, which frozen allows.)
        return _SECONDS_PER_MINUTE / (2.0 * math.pi * self.wheel_radius_m) * self.gear_ratio * self.pole_pairs

    def erpm_from_speed(self, speed_mps: float) -> float:
        return speed_mps * self.erpm_per_mps

    def speed_from_erpm(self, erpm: float) -> float:
        return erpm / self.erpm_per_mps

    @classmethod
    def from_table(cls, table: Table, wheel_radius_m: float, base_dir: Path | None = None) -> VescProfile:
        """Keys: controller_ids (6 distinct ints 0..254, default 1..6), pole_pairs (7), gear_ratio (20.0),
        dbc (a DBC file, relative to ``base_dir``, the config file's folder, or to the current directory
        without one; default "": the shipped DBC).

        A ``dbc`` file is loaded and checked here, so a config that names an unusable one is refused with
        the rest of the config, before anything runs."""
        ids = table.integers("controller_ids", list(DEFAULT_CONTROLLER_IDS), length=WHEEL_COUNT)
        if len(set(ids)) != WHEEL_COUNT:
            raise table.error("controller_ids", f"ids must be distinct, got {ids}")
        if not all(0 <= c <= MAX_CONTROLLER_ID for c in ids):
            raise table.error(
                "controller_ids", f"ids must be within 0..{MAX_CONTROLLER_ID}, got {ids} ({BROADCAST_NOTE})"
            )
        pole_pairs = table.integer("pole_pairs", 7, lo=1)
        gear_ratio = table.number("gear_ratio", 20.0, lo=1e-6)
        # Read even when absent, so a misspelt key is told about this one; "" is the default too.
        written = table.text("dbc", "")
        # Absolute: the codecs built later, and a recording's config record, must not depend on the cwd.
        dbc_path = table.file_path("dbc", base_dir or Path(), "DBC file").absolute() if written else None
        table.finish()
        if dbc_path is not None:
            try:
                load_vesc_database(ids, dbc_path)
            except DbcProfileError as err:
                raise table.error("dbc", str(err)) from err
        return cls(tuple(ids), pole_pairs, gear_ratio, wheel_radius_m, dbc_path)


def erpm_command(erpm: float) -> int:
    """The integer a SET_RPM frame carries for ``erpm``: rounded, clamped to int32."""
    if not math.isfinite(erpm):
        raise BridgeOperationError(f"cannot command a motor to {erpm} ERPM; give a finite number")
    command = round(erpm)
    # Six per control tick: comparisons, not min(max()) calls; the same clamp.
    if _INT32_MIN <= command <= _INT32_MAX:
        return command
    return _INT32_MAX if command > _INT32_MAX else _INT32_MIN


_new_message = can.Message.__new__


def data_frame(frame_id: int, length: int, data: bytes) -> can.Message:
    """``can.Message(arbitration_id=frame_id, is_extended_id=True, dlc=length, data=data)``: a classic
    data frame with a 29-bit id, as python-can's constructor (without ``check``) builds it.

    Hot path (every frame the senders encode: the simulated controllers' status and the link's SET_RPM,
    ~720 per simulated second): the constructor's call through the class, its thirteen parameters and its
    type tests on ``data`` cost a third more than writing the message's slots here (instructions,
    measured); the data is still copied into a ``bytearray`` of the message's own, as the constructor does.
    A test compares every slot with the constructor's message, so a python-can that adds one fails it."""
    msg = _new_message(can.Message)
    msg.timestamp = 0.0
    msg.arbitration_id = frame_id
    msg.is_extended_id = True
    msg.is_remote_frame = False
    msg.is_error_frame = False
    msg.channel = None
    msg.is_fd = False
    msg.is_rx = True
    msg.bitrate_switch = False
    msg.error_state_indicator = False
    msg.data = bytearray(data)
    msg.dlc = length
    return msg


@dataclass(slots=True)  # one per received frame (~720 per simulated second in a lockstep trial)
class VescFrame:
    """One decoded VESC frame: its kind ("SET_RPM", "STATUS", ...), controller id and physical values."""

    kind: str
    controller_id: int
    values: dict[str, float]


@dataclass(frozen=True, slots=True)
class FieldDecoder:
    """Chosen fields of one controller's message, read straight from a received frame
    (``VescCodec.field_decoders``).

    Hot path (the link's ~420 status frames and the simulated controllers' ~300 SET_RPM per simulated
    second): one call a frame, ``values(msg)``, gives the values the receiver wants, in its order, where
    ``decode`` builds a dict and a ``VescFrame``. It takes exactly the frames ``decode`` takes as this
    message (its frame id is the receiver's lookup key; a 29-bit id, not remote, dlc and data of the
    message's length) and gives ``decode``'s numbers (``FramePacker.frame_reader``); for any other frame
    it gives None and the receiver asks ``decode``, which refuses it with the reason (``FrameError``).
    """

    kind: str
    controller_id: int
    values: Callable[[can.Message], list[float] | None]
    length: int  # the message's data length: the dlc of every frame ``values`` accepts


class FrameEncoder:
    """One VESC message of one controller, encoded from values the caller has already clamped into their
    fields, without cantools' range check.

    Hot path (six SET_RPM per control tick, 6-18 status frames per 20 ms in the simulator): the
    message's ``FramePacker`` gives the bytes cantools' ``encode(values, strict=False)`` gives (a test
    compares them on random values) in under half the time; a message without one uses cantools.
    Senders keep one per message (``VescCodec.encoder``), so nothing is looked up per frame.
    """

    def __init__(self, message: cantools.database.can.Message, packer: FramePacker | None) -> None:
        self.message = message
        self._packer = packer
        self._frame_id = message.frame_id
        self._length = message.length  # a property cantools computes per access
        # The packer's pack, or cantools' encode: chosen once, not per frame.
        self._pack: Callable[[Mapping[str, float]], bytes] = (
            packer.pack if packer is not None else self._encode_with_cantools
        )

    def _encode_with_cantools(self, values: Mapping[str, float]) -> bytes:
        return bytes(self.message.encode(dict(values), strict=False))

    def encode(self, values: Mapping[str, float]) -> can.Message:
        try:
            data = self._pack(values)
        except (cantools.database.EncodeError, KeyError, ValueError, TypeError) as err:
            raise BridgeOperationError(
                f"cannot encode {self.message.name} from {dict(values)}: {err}"
            ) from err
        return can.Message(arbitration_id=self._frame_id, is_extended_id=True, data=data, dlc=self._length)

    def fields(self, names: Sequence[str], fixed: Mapping[str, float] | None = None) -> FieldEncoder:
        """An encoder of this message from the values of ``names`` in the caller's order, the other signals
        held at ``fixed`` (``FieldEncoder``)."""
        return FieldEncoder(self.message, self._packer, tuple(names), dict(fixed or {}))


class FieldEncoder:
    """One controller's message from the values of chosen signals, in the sender's order, the others held
    fixed (``FrameEncoder.fields``); values already clamped into their fields, as ``FrameEncoder``'s.

    Hot path (the simulated controllers' 6-18 status frames per 20 ms, the link's six SET_RPM per control
    tick): the sender keeps its values as numbers, not a dict per frame, and the held signals are converted
    once (``FramePacker.packing``); the same bytes as ``FrameEncoder.encode`` of the same values (a test
    compares them), cantools' for a message without a packer.
    """

    def __init__(
        self,
        message: cantools.database.can.Message,
        packer: FramePacker | None,
        names: tuple[str, ...],
        fixed: dict[str, float],
    ) -> None:
        self.message = message
        self._names = names
        self._fixed = fixed
        self._frame_id = message.frame_id
        self.length = message.length  # the data length (and dlc) of every frame it makes
        signals = sorted(signal.name for signal in message.signals)
        if signals != sorted([*names, *fixed]):
            raise BridgeSetupError(
                f"{message.name}: give each of its signals {signals} once, as a value or held fixed; "
                f"got values {list(names)} and fixed {sorted(fixed)}"
            )
        self._pack: Callable[[Sequence[float]], bytes] = (
            packer.packing(names, fixed) if packer is not None else self._encode_with_cantools
        )

    def _encode_with_cantools(self, values: Sequence[float]) -> bytes:
        return bytes(
            self.message.encode({**self._fixed, **dict(zip(self._names, values, strict=True))}, strict=False)
        )

    def encode(self, values: Sequence[float]) -> can.Message:
        try:
            data = self._pack(values)
        except (cantools.database.EncodeError, KeyError, ValueError, TypeError, IndexError) as err:
            raise BridgeOperationError(
                f"cannot encode {self.message.name} from {dict(zip(self._names, values, strict=False))} "
                f"(held: {self._fixed}): {err}"
            ) from err
        return data_frame(self._frame_id, self.length, data)


class VescCodec:
    """Encodes and decodes VESC frames defined by the DBC, strictly: bad frames raise ``FrameError``.

    Messages whose layout a ``FramePacker`` (derived from the same DBC message) can express are packed and
    unpacked by it on the hot paths, the rest by cantools: ``encode_in_range`` for senders whose values
    are already clamped into their fields (SET_RPM from the link, status from the simulated controllers),
    and ``decode`` for every received frame. Decoding stays strict either way: the id, frame format and
    length checks come first, and a payload of a plain whole-byte integer layout and the right length has
    no bit pattern cantools would refuse, so both decoders give the same numbers (a test compares them on
    random payloads).
    """

    @classmethod
    def for_profile(cls, profile: VescProfile) -> VescCodec:
        """The codec over the profile's DBC (its ``dbc_path``, or the shipped one): how the rover, the
        simulated controllers and the benches all build theirs, so each speaks the configured protocol."""
        return cls(load_vesc_database(profile.controller_ids, profile.dbc_path), profile)

    def __init__(self, database: cantools.database.can.Database, profile: VescProfile) -> None:
        self.database = database
        self.profile = profile
        # frame id -> (kind, controller id, message, its length, its packer or None): one lookup per
        # received frame. cantools' Message.length is a property computed per access.
        self._by_id: dict[int, tuple[str, int, cantools.database.can.Message, int, FramePacker | None]] = {}
        # (kind, controller id) -> its encoder, which also holds the message (``encode`` looks it up there).
        self._encoders: dict[tuple[str, int], FrameEncoder] = {}
        for cid in profile.controller_ids:
            for spec in VESC_MESSAGES:
                name = message_name(spec.kind, cid)
                try:
                    message = database.get_message_by_name(name)
                except KeyError as err:
                    raise BridgeSetupError(
                        f"the CAN database has no message {name}; generate it for controller ids "
                        f"{list(profile.controller_ids)} with firmware_bridge.vesc_dbc.generate_dbc"
                    ) from err
                if not message.is_extended_frame:
                    raise BridgeSetupError(f"{name} must use a 29-bit extended id in the DBC")
                packer = FramePacker.for_message(message)
                self._by_id[message.frame_id] = (spec.kind, cid, message, message.length, packer)
                self._encoders[(spec.kind, cid)] = FrameEncoder(message, packer)

    def encode(self, kind: str, controller_id: int, **values: float) -> can.Message:
        message = self.encoder(kind, controller_id).message
        try:
            data = message.encode(values)
        except (cantools.database.EncodeError, KeyError, ValueError, TypeError) as err:
            raise BridgeOperationError(f"cannot encode {message.name} from {values}: {err}") from err
        return can.Message(
            arbitration_id=message.frame_id, is_extended_id=True, data=data, dlc=message.length
        )

    def encode_set_rpm(self, controller_id: int, erpm: float) -> can.Message:
        """SET_RPM with the ERPM rounded to an integer and clamped to int32."""
        return self.encoder("SET_RPM", controller_id).encode({"erpm": erpm_command(erpm)})

    def encode_in_range(self, kind: str, controller_id: int, values: Mapping[str, float]) -> can.Message:
        """Encode values the caller has already clamped into their fields, without cantools' range check
        (``FrameEncoder.encode``)."""
        return self.encoder(kind, controller_id).encode(values)

    def encoder(self, kind: str, controller_id: int) -> FrameEncoder:
        """The encoder of one message, for senders that send it over and over: look it up once."""
        try:
            return self._encoders[(kind, controller_id)]
        except KeyError:
            raise BridgeOperationError(
                f"no VESC message {kind!r} for controller {controller_id}; known controllers "
                f"{list(self.profile.controller_ids)}, kinds {[m.kind for m in VESC_MESSAGES]}"
            ) from None

    def field_decoders(self, kind: str, names: Sequence[str]) -> dict[int, FieldDecoder]:
        """Frame id -> a ``FieldDecoder`` of ``names`` for each controller's ``kind`` message that a
        ``FramePacker`` decodes. A message without one (a swapped DBC's layout that ``struct`` cannot
        express) is left out: its frames go to ``decode``, as before."""
        decoders: dict[int, FieldDecoder] = {}
        for frame_id, (message_kind, cid, message, _, packer) in self._by_id.items():
            if message_kind != kind or packer is None:
                continue
            try:
                decoders[frame_id] = FieldDecoder(kind, cid, packer.frame_reader(names), message.length)
            except ValueError as err:
                raise BridgeSetupError(f"cannot read {list(names)} from {message.name}: {err}") from err
        return decoders

    def decode(self, msg: can.Message) -> VescFrame:
        """Strictly decode a received frame; raises ``FrameError`` with a ``reason`` on anything odd."""
        arbitration_id = msg.arbitration_id
        if not msg.is_extended_id:
            raise FrameError(
                f"CAN id 0x{arbitration_id:03x} is a standard 11-bit id; VESC frames use 29-bit ids",
                reason="not_extended",
                frame_id=arbitration_id,
            )
        entry = self._by_id.get(arbitration_id)
        if entry is None:
            raise FrameError(
                f"CAN id 0x{arbitration_id:08x} is not a VESC message of controllers "
                f"{list(self.profile.controller_ids)}",
                reason="unknown_id",
                frame_id=arbitration_id,
            )
        kind, cid, message, length, packer = entry
        data = msg.data
        if msg.is_remote_frame:
            # Its dlc is the length it asks for and it carries no data: "0 data bytes" would misname it.
            raise FrameError(
                f"{message.name} (id 0x{arbitration_id:08x}) came as a remote frame (a request for data, "
                f"dlc {msg.dlc}), not the data frame a controller sends",
                reason="wrong_dlc",
                frame_id=arbitration_id,
            )
        if msg.dlc != length or len(data) != length:
            raise FrameError(
                f"{message.name} (id 0x{arbitration_id:08x}) has {len(data)} data bytes (dlc {msg.dlc}), "
                f"expected {length}",
                reason="wrong_dlc",
                frame_id=arbitration_id,
            )
        if packer is not None:
            return VescFrame(kind, cid, packer.unpack(data))
        try:
            decoded = message.decode(bytes(data), decode_choices=False)
        except (cantools.database.DecodeError, ValueError) as err:
            raise FrameError(
                f"cannot decode {message.name} (id 0x{arbitration_id:08x}): {err}",
                reason="decode",
                frame_id=arbitration_id,
            ) from err
        values: dict[str, float] = {}
        if isinstance(decoded, dict):
            for name, value in decoded.items():
                if not isinstance(value, (int, float)):  # a tuple: faster per frame than int | float
                    break
                values[name] = float(value)
            else:
                return VescFrame(kind, cid, values)
        raise FrameError(
            f"{message.name} (id 0x{arbitration_id:08x}) did not decode to numbers: {decoded!r}",
            reason="decode",
            frame_id=arbitration_id,
        )
