"""The VESC CAN protocol as data, and the DBC text generated from it.

Facts from the VESC firmware documentation (see ../shared/reference/vesc_can.md): 29-bit extended ids
``(command_id << 8) | controller_id``, big-endian signed fields, value = raw / scale. The shipped
``vesc_6wheel.dbc`` is ``generate_dbc(DEFAULT_CONTROLLER_IDS)``; a test keeps the two identical.

A team whose controllers run other firmware swaps in its own DBC (``[vesc] dbc``): ``load_vesc_database``
loads it instead and ``check_vesc_database`` refuses it, before anything runs, unless it has what the codec
looks up by name (``VescCodec``): every message of ``VESC_MESSAGES`` for every controller id, with a 29-bit
id and exactly the signals named here. Layout, scaling, byte order, lengths and command ids are the file's.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from decimal import ROUND_DOWN, Context, Decimal
from importlib import resources
from pathlib import Path

import cantools
import cantools.database

from firmware_bridge.errors import BridgeSetupError, DbcProfileError

DEFAULT_CONTROLLER_IDS: tuple[int, ...] = (1, 2, 3, 4, 5, 6)
SHIPPED_DBC_NAME = "vesc_6wheel.dbc"
# The VESC firmware obeys a command addressed to 255 whatever its own id (comm_can.c: ``id == 255 ||
# id == controller_id``): a wheel given id 255 would drive all six, so the highest usable id is 254.
BROADCAST_CONTROLLER_ID = 255
MAX_CONTROLLER_ID = BROADCAST_CONTROLLER_ID - 1
BROADCAST_NOTE = "255 is the VESC broadcast id: every controller obeys a command sent to it"

# DBC marks a 29-bit frame id by setting bit 31 of the number written in the file.
_DBC_EXTENDED_FLAG = 0x8000_0000
_COMPANION_NODE = "COMPANION"
_VESC_NODE = "VESC"


@dataclass(frozen=True)
class VescSignal:
    """One big-endian signed integer field: value = raw / scale."""

    name: str
    start_byte: int
    length_bytes: int
    scale: int
    unit: str = ""


@dataclass(frozen=True)
class VescMessage:
    kind: str
    command_id: int
    length: int
    from_controller: bool
    signals: tuple[VescSignal, ...]


VESC_MESSAGES: tuple[VescMessage, ...] = (
    VescMessage("SET_DUTY", 0, 4, False, (VescSignal("duty", 0, 4, 100000),)),
    VescMessage("SET_CURRENT", 1, 4, False, (VescSignal("current", 0, 4, 1000, "A"),)),
    VescMessage("SET_CURRENT_BRAKE", 2, 4, False, (VescSignal("current", 0, 4, 1000, "A"),)),
    VescMessage("SET_RPM", 3, 4, False, (VescSignal("erpm", 0, 4, 1, "rpm"),)),
    VescMessage(
        "STATUS",
        9,
        8,
        True,
        (
            VescSignal("erpm", 0, 4, 1, "rpm"),
            VescSignal("current", 4, 2, 10, "A"),
            VescSignal("duty", 6, 2, 1000),
        ),
    ),
    VescMessage(
        "STATUS_2",
        14,
        8,
        True,
        (VescSignal("amp_hours", 0, 4, 10000, "Ah"), VescSignal("amp_hours_charged", 4, 4, 10000, "Ah")),
    ),
    VescMessage(
        "STATUS_3",
        15,
        8,
        True,
        (VescSignal("watt_hours", 0, 4, 10000, "Wh"), VescSignal("watt_hours_charged", 4, 4, 10000, "Wh")),
    ),
    VescMessage(
        "STATUS_4",
        16,
        8,
        True,
        (
            VescSignal("temp_fet", 0, 2, 10, "degC"),
            VescSignal("temp_motor", 2, 2, 10, "degC"),
            VescSignal("current_in", 4, 2, 10, "A"),
            VescSignal("pid_pos", 6, 2, 50, "deg"),
        ),
    ),
    # The firmware sends 8 bytes: tachometer, input voltage, then two reserved bytes.
    VescMessage(
        "STATUS_5",
        27,
        8,
        True,
        (VescSignal("tacho", 0, 4, 6, "erev"), VescSignal("voltage_in", 4, 2, 10, "V")),
    ),
)

MESSAGES_BY_KIND: dict[str, VescMessage] = {m.kind: m for m in VESC_MESSAGES}


def frame_id(command_id: int, controller_id: int) -> int:
    """The 29-bit CAN id of a VESC command or status for one controller."""
    return (command_id << 8) | controller_id


def message_name(kind: str, controller_id: int) -> str:
    return f"VESC_{kind}_C{controller_id}"


# Decimal arithmetic keeps the file free of binary float artefacts (3276.7000000000003); rounding the
# limits toward zero keeps every value inside them encodable.
_DIGITS = Context(prec=17)
_LIMIT_DIGITS = Context(prec=17, rounding=ROUND_DOWN)


def _number(value: Decimal) -> str:
    """A DBC number written positionally (no exponent), without trailing zeros."""
    text = format(value, "f")
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return text


def _signal_line(signal: VescSignal, receiver: str) -> str:
    bits = 8 * signal.length_bytes
    # Motorola (@0) signals are located by their most significant bit, numbered as in Intel order.
    start_bit = 8 * signal.start_byte + 7
    scale = Decimal(signal.scale)
    factor = _DIGITS.divide(Decimal(1), scale)
    low = _LIMIT_DIGITS.divide(Decimal(-(1 << (bits - 1))), scale)
    high = _LIMIT_DIGITS.divide(Decimal((1 << (bits - 1)) - 1), scale)
    return (
        f" SG_ {signal.name} : {start_bit}|{bits}@0- ({_number(factor)},0) "
        f'[{_number(low)}|{_number(high)}] "{signal.unit}" {receiver}'
    )


def _check_ids(controller_ids: Sequence[int]) -> None:
    if not controller_ids:
        raise BridgeSetupError("no VESC controller ids given; pass e.g. [1, 2, 3, 4, 5, 6]")
    if len(set(controller_ids)) != len(controller_ids):
        raise BridgeSetupError(f"VESC controller ids must be distinct, got {list(controller_ids)}")
    for cid in controller_ids:
        if isinstance(cid, bool) or not isinstance(cid, int) or not 0 <= cid <= MAX_CONTROLLER_ID:
            raise BridgeSetupError(
                f"VESC controller id must be an integer 0..{MAX_CONTROLLER_ID}, got {cid!r}; {BROADCAST_NOTE}"
            )


def generate_dbc(controller_ids: Sequence[int]) -> str:
    """DBC text describing every VESC message for each controller id, in the order given."""
    _check_ids(controller_ids)
    lines = [
        'VERSION ""',
        "",
        "NS_ :",
        "",
        "BS_:",
        "",
        f"BU_: {_COMPANION_NODE} {_VESC_NODE}",
        "",
    ]
    for cid in controller_ids:
        for message in VESC_MESSAGES:
            sender, receiver = (
                (_VESC_NODE, _COMPANION_NODE) if message.from_controller else (_COMPANION_NODE, _VESC_NODE)
            )
            dbc_id = frame_id(message.command_id, cid) | _DBC_EXTENDED_FLAG
            lines.append(f"BO_ {dbc_id} {message_name(message.kind, cid)}: {message.length} {sender}")
            lines.extend(_signal_line(signal, receiver) for signal in message.signals)
            lines.append("")
    comment = "VESC CAN protocol, generated by firmware_bridge.vesc_dbc.generate_dbc"
    lines.append(f'CM_ "{comment} for controller ids {" ".join(map(str, controller_ids))}";')
    return "\n".join(lines) + "\n"


def load_vesc_database(
    controller_ids: Sequence[int] = DEFAULT_CONTROLLER_IDS, dbc_path: Path | None = None
) -> cantools.database.can.Database:
    """The cantools database for these controllers: the file at ``dbc_path`` when given (checked with
    ``check_vesc_database``; ``DbcProfileError`` if it is unusable), else the shipped file for the default
    ids and a generated one for others.

    Parsed once per process and shared (read it, never change it): a DBC takes ~9 ms to parse, which a
    lockstep trial paid for every codec, and a campaign worker for every trial; loading a rover config
    with a team's file checks it and then builds the codec from it. A team's file is parsed again when
    its modification time or size has changed since.
    """
    _check_ids(controller_ids)
    ids = tuple(controller_ids)
    if dbc_path is None:
        return _packaged_database(ids)
    try:
        status = dbc_path.stat()
    except OSError:
        return _checked_team_database(ids, dbc_path, None)  # not cached: _load_dbc_file names the error
    return _checked_team_database(ids, dbc_path, (status.st_mtime_ns, status.st_size))


@functools.lru_cache(maxsize=16)
def _checked_team_database(
    controller_ids: tuple[int, ...], dbc_path: Path, file_stamp: tuple[int, int] | None
) -> cantools.database.can.Database:
    """``file_stamp`` (modification time, size) is only part of the cache key: an edited file is new."""
    team_database = _load_dbc_file(dbc_path)
    check_vesc_database(team_database, controller_ids, str(dbc_path))
    return team_database


@functools.lru_cache(maxsize=16)
def _packaged_database(controller_ids: tuple[int, ...]) -> cantools.database.can.Database:
    try:
        if controller_ids == DEFAULT_CONTROLLER_IDS:
            path = resources.files("firmware_bridge").joinpath(SHIPPED_DBC_NAME)
            with resources.as_file(path) as shipped_path:
                database = cantools.database.load_file(str(shipped_path), database_format="dbc")
        else:
            database = cantools.database.load_string(generate_dbc(controller_ids), database_format="dbc")
    except (cantools.database.UnsupportedDatabaseFormatError, cantools.database.Error, OSError) as err:
        raise BridgeSetupError(
            f"cannot load the VESC DBC for controller ids {list(controller_ids)}: {err}; "
            "regenerate firmware_bridge/vesc_6wheel.dbc with generate_dbc()"
        ) from err
    if not isinstance(database, cantools.database.can.Database):
        raise BridgeSetupError("the VESC DBC did not load as a CAN database")
    return database


def _load_dbc_file(path: Path) -> cantools.database.can.Database:
    """A team's DBC file, loaded strictly as DBC (no guessing the format from the suffix)."""
    try:
        database = cantools.database.load_file(str(path), database_format="dbc")
    except OSError as err:
        raise DbcProfileError(f"VESC DBC {path}: cannot read the file: {err.strerror or err}") from err
    # What cantools raises on text that is not a DBC it accepts (its parser, its strict signal checks), and
    # a decoder error on bytes that are not text at all.
    except (cantools.database.Error, UnicodeDecodeError, ValueError, KeyError, IndexError) as err:
        problem = " ".join(str(err).split())  # its parse errors quote the line: keep the report on one
        raise DbcProfileError(f"VESC DBC {path}: not a DBC file cantools can load: {problem}") from err
    if not isinstance(database, cantools.database.can.Database):
        raise DbcProfileError(f"VESC DBC {path}: did not load as a CAN database")
    return database


def check_vesc_database(
    database: cantools.database.can.Database, controller_ids: Sequence[int], source: str
) -> None:
    """Refuse (``DbcProfileError`` naming ``source``, the message and what is wrong) a database the codec
    cannot run on: for every controller id, every ``VESC_MESSAGES`` kind as ``VESC_<KIND>_C<id>`` with a
    29-bit id of its own, not multiplexed, holding exactly the signals named there."""
    owner_by_id: dict[int, str] = {}
    for cid in controller_ids:
        for spec in VESC_MESSAGES:
            name = message_name(spec.kind, cid)
            try:
                message = database.get_message_by_name(name)
            except KeyError:
                raise DbcProfileError(
                    f"VESC DBC {source}: no message {name} (the {spec.kind} frame of controller {cid}); the "
                    f"stack looks up VESC_<KIND>_C<id> for every id in [vesc] controller_ids "
                    f"{list(controller_ids)}"
                ) from None
            if not message.is_extended_frame:
                raise DbcProfileError(
                    f"VESC DBC {source}: {name} has the standard 11-bit id 0x{message.frame_id:03x}; VESC "
                    "frames use 29-bit extended ids (in a DBC file: the id with bit 31 set, 0x80000000)"
                )
            if message.is_multiplexed() or message.is_container:
                raise DbcProfileError(
                    f"VESC DBC {source}: {name} is multiplexed; the codec reads plain frames"
                )
            _check_signals(message, spec, source)
            owner = owner_by_id.setdefault(message.frame_id, name)
            if owner != name:
                raise DbcProfileError(
                    f"VESC DBC {source}: {name} and {owner} share the id 0x{message.frame_id:08x}; the codec "
                    "tells received frames apart by id"
                )


def _check_signals(message: cantools.database.can.Message, spec: VescMessage, source: str) -> None:
    """Exactly the signals ``spec`` names: the stack reads them by name, and encodes every signal of a
    message (SET_RPM on the rover, the status frames in the simulated controllers), so one more is a
    value nobody supplies."""
    wanted = [signal.name for signal in spec.signals]
    present = {signal.name for signal in message.signals}
    missing = [name for name in wanted if name not in present]
    if missing:
        raise DbcProfileError(
            f"VESC DBC {source}: {message.name} has no signal {missing[0]!r} (the stack needs "
            f"{', '.join(wanted)})"
        )
    extra = sorted(present.difference(wanted))
    if extra:
        raise DbcProfileError(
            f"VESC DBC {source}: {message.name} has a signal {extra[0]!r} the stack does not know; it "
            f"encodes every signal of a message, so {spec.kind} may hold only {', '.join(wanted)}"
        )
