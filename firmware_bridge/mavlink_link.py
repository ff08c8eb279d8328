"""The companion's MAVLink 2 link to the autopilot: heartbeats out, GPS and IMU in, every frame recorded.

MAVLink reports the IMU in the body frame x forward, y right, z down (FRD); our ``sensors/imu`` topic
and ``ImuSample`` use x forward, y left, z up (FLU), so y and z change sign here, once.
"""

from __future__ import annotations

import binascii
import logging
import math
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.distance_sensor import BeamRejected, RangeBeam, read_beam
from firmware_bridge.errors import BridgeOperationError, BridgeSetupError
from firmware_bridge.mavlink_budget import (
    DEFAULT_RATE_BYTES_PER_S,
    ReceiveBudget,
    admit_datagrams,
    admit_stream,
)
from firmware_bridge.mavlink_commands import (
    COMMAND_MESSAGES,
    GoalRequest,
    StopRequest,
    addressed_to,
    is_mission_start,
    judge_command,
    statustext_chunks,
)
from firmware_bridge.mavlink_frames import V2_FRAME_OVERHEAD, decode_unsigned_v2
from firmware_bridge.mavlink_health import MavlinkCounters, MavlinkHealth
from firmware_bridge.mavlink_home import is_home_command
from firmware_bridge.mavlink_mission import (
    MISSION_MESSAGE_IDS,
    MISSION_MESSAGES,
    MissionMessage,
    mission_addressed,
)
from firmware_bridge.mavlink_transport import DatagramTransport, Transport, check_connection
from firmware_bridge.obstacle_scan import ObstacleScan, ScanRejected, read_scan
from logs.clock import Clock, to_ns
from logs.closing import ClosesOnExit
from logs.encoding import bytes_only_sink
from logs.settings import Table
from logs.sink import MessageSink
from logs.topics import MAVLINK_RAW, MAVLINK_STATS, SAFETY_EVENTS, SENSORS_GPS, SENSORS_IMU, stamp

logger = logging.getLogger(__name__)

STANDARD_GRAVITY_MPS2 = 9.80665
_MG_TO_MPS2 = STANDARD_GRAVITY_MPS2 / 1000.0
_MRAD_TO_RAD = 1e-3
_UINT16_UNKNOWN = 65535
_GPS_FRAME_ID = "gps"
_IMU_FRAME_ID = "base_link"
_COVARIANCE_UNKNOWN = 0
_COVARIANCE_DIAGONAL_KNOWN = 2


@dataclass(frozen=True)
class MavlinkConfig:
    connection: str = "memory"
    system_id: int = 1
    component_id: int = 191
    autopilot_system_id: int = 1
    allow_remote: bool = False  # only the real vehicle may talk to a non-loopback address
    link_timeout_s: float = 3.0  # no autopilot HEARTBEAT (1 Hz) for this long: the link is lost
    signing_key: str = ""  # 64 hex digits (32 bytes) turn MAVLink 2 signing on; empty: off
    # Received bytes parsed per second at most; a flood beyond it is dropped unread (mavlink_budget).
    rx_budget_bytes_per_s: int = DEFAULT_RATE_BYTES_PER_S

    @classmethod
    def from_table(cls, table: Table) -> MavlinkConfig:
        """Keys: connection, system_id, component_id, autopilot_system_id, allow_remote, link_timeout_s,
        signing_key, rx_budget_bytes_per_s (all optional)."""
        d = cls()
        config = cls(
            connection=table.text("connection", d.connection),
            system_id=table.integer("system_id", d.system_id, lo=1, hi=255),
            component_id=table.integer("component_id", d.component_id, lo=1, hi=255),
            autopilot_system_id=table.integer("autopilot_system_id", d.autopilot_system_id, lo=1, hi=255),
            allow_remote=table.flag("allow_remote", d.allow_remote),
            link_timeout_s=table.number("link_timeout_s", d.link_timeout_s, lo=0.1, hi=600.0),
            signing_key=table.text("signing_key", d.signing_key),
            rx_budget_bytes_per_s=table.integer(
                "rx_budget_bytes_per_s", d.rx_budget_bytes_per_s, lo=1024, hi=100_000_000
            ),
        )
        try:
            check_connection(config.connection, allow_remote=config.allow_remote)
        except BridgeSetupError as err:
            raise table.error("connection", str(err)) from None
        if config.signing_key:
            try:
                signing_key_bytes(config.signing_key)
            except BridgeSetupError as err:
                raise table.error("signing_key", str(err)) from None
        table.finish()
        return config


def signing_key_bytes(text: str) -> bytes:
    """The 32-byte MAVLink 2 secret key from its 64-hex-digit spelling in the config."""
    try:
        key = bytes.fromhex(text)
    except ValueError:
        key = b""
    if len(key) != 32:
        raise BridgeSetupError("a MAVLink signing key is 64 hex digits (32 bytes)")
    return key


@dataclass(frozen=True)
class GpsFix:
    """GPS_RAW_INT in SI units, passed through faithfully (the estimator judges validity).

    ``eph_m`` / ``speed_mps`` / ``course_rad`` are NaN where MAVLink says unknown. ``course_rad`` is the
    course over ground in our convention: radians counter-clockwise from east (not a compass bearing).
    """

    t_ns: int
    lat_deg: float
    lon_deg: float
    alt_m: float
    fix_type: int
    satellites: int
    eph_m: float
    speed_mps: float
    course_rad: float


class ImuSample(NamedTuple):
    """Body-frame (x forward, y left, z up) angular rate in rad/s and specific force in m/s^2.

    A NamedTuple (immutable, like the other readings' frozen dataclasses): one arrives every control tick,
    and a frozen dataclass sets each field through ``object.__setattr__``, about three times the cost."""

    t_ns: int
    gyro_xyz_rps: tuple[float, float, float]
    accel_xyz_mps2: tuple[float, float, float]


@dataclass(frozen=True)
class AttitudeSample:
    """ATTITUDE from the autopilot's AHRS: roll, pitch (rad) and yaw in our convention (rad CCW from east).

    MAVLink's yaw is NED (clockwise from north); it is converted here, once.
    """

    t_ns: int
    roll_rad: float
    pitch_rad: float
    yaw_rad: float


@dataclass(frozen=True)
class BatteryState:
    """SYS_STATUS / BATTERY_STATUS: volts, amps (NaN unknown), remaining percent (-1 unknown)."""

    t_ns: int
    voltage_v: float
    current_a: float
    remaining_pct: int
    source: str


Reading = (
    GpsFix
    | ImuSample
    | AttitudeSample
    | BatteryState
    | ObstacleScan
    | RangeBeam
    | GoalRequest
    | StopRequest
    | MissionMessage
)

# The first refused OBSTACLE_DISTANCE (DISTANCE_SENSOR) is logged, then every 100th.
_LOG_REJECTED_RANGE_EVERY = 100


class _TransportFile:
    """The file-like object pymavlink writes packed frames to."""

    def __init__(self, transport: Transport) -> None:
        self._transport = transport

    def write(self, data: bytes) -> None:
        self._transport.write(bytes(data))


def _header_fields(frame: bytes) -> tuple[int, int, int]:
    """(msgid, sysid, compid) straight from a frame's header (MAVLink 2 or 1), as pymavlink reads them."""
    if frame[0] == mavlink2.PROTOCOL_MARKER_V2 and len(frame) >= 10:
        return frame[7] | frame[8] << 8 | frame[9] << 16, frame[5], frame[6]
    if len(frame) >= 6:
        return frame[5], frame[3], frame[4]
    return -1, 0, 0


def _garbage_kind(reason: str) -> str:
    """The counter for one of pymavlink's robust-parsing reasons."""
    if reason == "Bad prefix":
        return "noise"
    if reason.startswith("invalid MAVLink CRC"):
        return "bad_crc"
    return "bad_header"  # incompat flags, length or an unpackable header


def compass_to_enu_rad(bearing_deg: float) -> float:
    """A compass bearing (degrees clockwise from north) as radians CCW from east, in (-pi, pi]."""
    angle = math.radians(90.0 - bearing_deg)
    return math.atan2(math.sin(angle), math.cos(angle))


class MavlinkLink(ClosesOnExit):
    """Our MAVLink component on the companion computer (``MAV_TYPE_ONBOARD_CONTROLLER``).

    ``autopilot_system_id`` (optional) keeps sensors and heartbeats from other systems out.
    ``rx_budget_bytes_per_s`` bounds the bytes parsed per second of the clock (``mavlink_budget``);
    ``name`` tells this link's ``mavlink/stats`` and warnings from another's (a ground-station link).
    """

    def __init__(
        self,
        transport: Transport,
        clock: Clock,
        sink: MessageSink,
        system_id: int = 1,
        component_id: int = 191,
        *,
        autopilot_system_id: int | None = None,
        link_timeout_s: float | None = 3.0,  # None: no autopilot on this link (a ground-station link)
        signing_key: bytes | None = None,
        rx_budget_bytes_per_s: int = DEFAULT_RATE_BYTES_PER_S,
        name: str = "autopilot",
    ) -> None:
        self._transport = transport
        # UDP keeps message boundaries: each datagram is parsed on its own (DatagramTransport).
        self._datagrams = transport if isinstance(transport, DatagramTransport) else None
        self._clock = clock
        self._sink = sink
        # A sink that records bytes alone (the recorder, Zenoh, a fan-out of those) gets each frame's
        # mavlink/raw record formatted straight to its JSON (_raw_json), with no dict built and encoded.
        self._bytes_sink = bytes_only_sink(sink)
        self.system_id = system_id
        self.component_id = component_id
        self._autopilot_system_id = autopilot_system_id
        self._signing: mavlink2.MAVLinkSigning | None = None
        if signing_key is not None:
            if len(signing_key) != 32:
                raise BridgeSetupError("a MAVLink signing key is 32 bytes")
            self._signing = mavlink2.MAVLinkSigning()
            self._signing.secret_key = signing_key
            self._signing.sign_outgoing = True
            # Telemetry may come unsigned (many autopilots sign nothing); commands never may.
            self._signing.allow_unsigned_callback = _allow_unsigned
        self._mav = self._new_mavlink()
        self.counters = MavlinkCounters()
        self.name = name
        self._budget = ReceiveBudget(rx_budget_bytes_per_s, clock.now_ns())
        self._health = MavlinkHealth(clock.now_ns(), self.counters, name)
        self.last_heartbeat_ns: int | None = None
        self._link_timeout_ns = None if link_timeout_s is None else to_ns(link_timeout_s)
        self._started_ns = clock.now_ns()
        self.autopilot_link_ok = True
        self._statustext_id = 0
        self._closed = False
        self._converters = self._new_converters()

    def _new_mavlink(self) -> mavlink2.MAVLink:
        mav = mavlink2.MAVLink(_TransportFile(self._transport), self.system_id, self.component_id)
        # Robust parsing turns garbage into BAD_DATA messages instead of exceptions, so we can count it.
        mav.robust_parsing = True
        if self._signing is not None:
            # One signing state for the life of the link: its stream timestamps are the replay guard.
            mav.signing = self._signing
        return mav

    def start_watch(self, now_ns: int) -> None:
        """Count the autopilot's silence (``mavlink_link_lost``), until its first HEARTBEAT, from ``now_ns``
        instead of from construction: the control loop calls this on its first tick, so a long start-up
        between opening the link and using it is not reported as a lost autopilot."""
        self._started_ns = now_ns

    # --- sending -------------------------------------------------------------------------------
    def send(self, msg: Any) -> None:
        """Pack with our ids and sequence, write, record. A failed write is counted and logged."""
        t_ns = self._clock.now_ns()
        try:
            self._mav.send(msg)
        except (BridgeOperationError, OSError) as err:
            self.counters.tx_errors += 1
            logger.warning("MAVLink send of %s failed: %s", msg.get_type(), err)
            return
        self.counters.tx_frames += 1
        self._publish_raw(
            t_ns,
            "tx",
            bytes(msg.get_msgbuf()),
            msg.get_msgId(),
            msg.get_type(),
            self.system_id,
            self.component_id,
        )

    def send_heartbeat(self) -> None:
        self.send(
            self._mav.heartbeat_encode(
                mavlink2.MAV_TYPE_ONBOARD_CONTROLLER,
                mavlink2.MAV_AUTOPILOT_INVALID,
                0,
                0,
                mavlink2.MAV_STATE_ACTIVE,
            )
        )

    def send_status_text(self, text: str, severity: int = mavlink2.MAV_SEVERITY_INFO) -> None:
        """Tell the ground station something in STATUSTEXT (chunked past 50 bytes)."""
        chunks = statustext_chunks(text)
        if len(chunks) == 1:
            self.send(self._mav.statustext_encode(severity, chunks[0]))
            return
        self._statustext_id = self._statustext_id % 65535 + 1
        for seq, chunk in enumerate(chunks):
            self.send(self._mav.statustext_encode(severity, chunk, self._statustext_id, seq))

    def _publish_raw(
        self, t_ns: int, direction: str, frame: bytes, msgid: int, name: str, sysid: int, compid: int
    ) -> None:
        # base64.b64encode's own call, without its Python wrapper: ~70 frames a simulated second.
        data = binascii.b2a_base64(frame, newline=False).decode("ascii")
        if self._bytes_sink is not None and name in _DIALECT_NAMES:
            self._bytes_sink.publish_bytes(
                MAVLINK_RAW, t_ns, _raw_json(t_ns, direction, msgid, name, sysid, compid, data)
            )
            return
        self._sink.publish(MAVLINK_RAW, t_ns, _raw_record(t_ns, direction, msgid, name, sysid, compid, data))

    # --- receiving -----------------------------------------------------------------------------
    def poll(self) -> list[Reading]:
        """Read and parse what arrived (within the receive budget); return readings (sensors, battery,
        goals, stops, mission messages addressed to us) in arrival order.

        Goals and stops addressed to us are answered here (COMMAND_ACK or the target echo) before they are
        returned; a ``StopRequest`` is also recorded on ``safety/events`` (kind ``mavlink_stop_request``).
        Once a second the link's counts go to ``mavlink/stats``; garbage is summed up in a WARNING at most
        every five seconds (``firmware_bridge.mavlink_health``).
        """
        t_ns = self._clock.now_ns()
        readings: list[Reading] = []
        for chunk in self._admitted(t_ns):
            for msg in self._parse(chunk):
                self._take(msg, t_ns, readings)
            if self._datagrams is not None:
                # A frame never spans two datagrams: what is left is cut short, not waiting for more.
                self._drop_partial_frame()
        limit_ns = self._link_timeout_ns
        if limit_ns is not None:
            # The autopilot's silence, judged at every poll (inline: a call fewer on the usual poll).
            last = self.last_heartbeat_ns
            silent_ns = t_ns - (self._started_ns if last is None else last)
            ok = silent_ns <= limit_ns
            if ok != self.autopilot_link_ok:
                self._link_changed(t_ns, ok, silent_ns, limit_ns)
        # A health window closes once a second at most: the health is asked only when one may close.
        if t_ns >= self._health.next_close_ns:
            self._report_health(t_ns)
        return readings

    def _admitted(self, t_ns: int) -> list[bytes]:
        """What arrived, cut to the receive budget; the rest is counted in ``dropped_bytes``."""
        allowance = self._budget.allowance(t_ns)
        if self._datagrams is not None:
            kept, dropped = admit_datagrams(self._datagrams.read_datagrams(), allowance)
            kept_bytes = sum(len(chunk) for chunk in kept)
        else:
            data, dropped = admit_stream(self._transport.read(), allowance)
            kept = [data] if data else []
            kept_bytes = len(data)
            if dropped:
                # The frame whose start the parser holds went on in the bytes just dropped.
                self._drop_partial_frame()
        if dropped:
            self.counters.dropped_bytes += dropped
            logger.debug("MAVLink receive budget: dropped %d bytes unread", dropped)
        self._budget.spend(kept_bytes)
        return kept

    def _take(self, msg: Any, t_ns: int, readings: list[Reading]) -> None:
        frame = msg.get_msgbuf()  # the decoded frame's own bytes (read only: recorded, header read)
        kind = msg.get_type()
        # The ids from the frame's header, where pymavlink's decode read them too: one call, not three
        # getters per frame (and the only way for a frame of an id the dialect does not know).
        msgid, sysid, compid = _header_fields(frame)
        if isinstance(msg, mavlink2.MAVLink_unknown):
            self.counters.unknown_frames += 1
        self.counters.rx_frames += 1
        self._publish_raw(t_ns, "rx", frame, msgid, kind, sysid, compid)
        if kind in COMMAND_MESSAGES:
            if is_mission_start(msg) or is_home_command(msg):
                # The mission server's (it holds the mission the start is judged against) or the onboard
                # stack's home's (firmware_bridge.mavlink_home), addressed as mission messages are: a
                # component-broadcast start or home request on the autopilot's link is the autopilot's own.
                if mission_addressed(msg, self.system_id, self.component_id):
                    readings.append(MissionMessage(msg, t_ns))
                return
            request = self._answer_command(msg, t_ns)
            if request is not None:
                readings.append(request)
            return
        if kind in MISSION_MESSAGES:
            # From any system, as commands are (a ground station's); answered by the onboard stack's
            # mission server (firmware_bridge.mavlink_mission), which owns the mission in force.
            if mission_addressed(msg, self.system_id, self.component_id):
                readings.append(MissionMessage(msg, t_ns))
            return
        if self._autopilot_system_id is not None and sysid != self._autopilot_system_id:
            return
        convert = self._converters.get(kind)
        if convert is not None:
            reading = convert(msg, t_ns)
            if reading is not None:
                readings.append(reading)

    def _report_health(self, t_ns: int) -> None:
        report = self._health.report(t_ns, self.counters)
        if report.stats is not None:
            self._sink.publish(MAVLINK_STATS, t_ns, report.stats)
        if report.warning is not None:
            logger.warning("%s", report.warning)

    def _answer_command(self, msg: Any, t_ns: int) -> GoalRequest | StopRequest | None:
        if not addressed_to(msg, self.system_id, self.component_id):
            return None
        verdict = judge_command(msg, t_ns)
        if verdict.stop is not None:
            self._record_stop(verdict.stop, verdict.reason)
        elif verdict.goal is not None:
            self.counters.goals_accepted += 1
            logger.info("goal %.7f, %.7f from %d/%d", verdict.goal.lat_deg, verdict.goal.lon_deg, *_src(msg))
        else:
            self.counters.commands_rejected += 1
            logger.warning("refused %s from %d/%d: %s", msg.get_type(), *_src(msg), verdict.reason)
        if msg.get_type() == "SET_POSITION_TARGET_GLOBAL_INT" and verdict.goal is not None:
            # The standard answer to a position target is the target as now followed.
            self.send(
                self._mav.position_target_global_int_encode(
                    int(t_ns // 1_000_000) & 0xFFFFFFFF,
                    msg.coordinate_frame,
                    msg.type_mask,
                    msg.lat_int,
                    msg.lon_int,
                    msg.alt,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                )
            )
        else:
            command = getattr(msg, "command", mavlink2.MAV_CMD_DO_REPOSITION)
            self.send(
                self._mav.command_ack_encode(
                    command, verdict.result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
                )
            )
        if verdict.stop is not None:
            return verdict.stop
        if verdict.goal is None:
            self.send_status_text(f"refused: {verdict.reason}", mavlink2.MAV_SEVERITY_WARNING)
        return verdict.goal

    def _record_stop(self, stop: StopRequest, reason: str) -> None:
        self.counters.stops_accepted += 1
        detail = f"{reason} ({stop.source} from {stop.sysid}/{stop.compid})"
        logger.warning("mavlink_stop_request: %s", detail)
        self._sink.publish(
            SAFETY_EVENTS,
            stop.t_ns,
            {
                "timestamp": stamp(stop.t_ns),
                "kind": "mavlink_stop_request",
                "severity": "error",
                "detail": detail,
            },
        )

    def _link_changed(self, t_ns: int, ok: bool, silent_ns: int, limit_ns: int) -> None:
        """The autopilot's link came back (``ok``) or went down, silent ``silent_ns`` past the timeout
        ``limit_ns``: log and record it."""
        self.autopilot_link_ok = ok
        if ok:
            kind, severity, detail = "mavlink_link_restored", "info", "autopilot HEARTBEAT received again"
        else:
            kind, severity = "mavlink_link_lost", "error"
            limit_s = limit_ns / 1e9
            detail = f"no autopilot HEARTBEAT for {silent_ns / 1e9:.1f} s (limit {limit_s:.1f} s)"
        (logger.info if ok else logger.warning)("%s: %s", kind, detail)
        self._sink.publish(
            SAFETY_EVENTS,
            t_ns,
            {"timestamp": stamp(t_ns), "kind": kind, "severity": severity, "detail": detail},
        )

    def _parse(self, data: bytes) -> list[Any]:
        messages: list[Any] = []
        if self._signing is None and not self._mav.buf_len():
            # The usual read: whole frames and nothing held from the last one. Those are decoded without
            # pymavlink's byte-stream parser; from the first byte that is anything else on, it parses.
            taken = self._decode_whole_frames(data, messages)
            if taken == len(data):
                return messages
            data = data[taken:]
        pending = data
        while True:
            try:
                msg = self._mav.parse_char(pending)
            except (mavlink2.MAVError, struct.error, ValueError, IndexError) as err:
                # Should not happen with robust parsing; if it does, drop what is buffered and go on.
                self._count_bad(len(self._mav.buf) - self._mav.buf_index, "bad_header", str(err))
                self._mav = self._new_mavlink_keeping_sequence()
                break
            pending = b""
            if msg is None:
                break
            if isinstance(msg, mavlink2.MAVLink_bad_data):
                if msg.reason == "Invalid signature":
                    # A whole, CRC-correct frame refused by the signing check: nothing to rescan. The first
                    # is logged at once; the rest are summed up in the link's periodic warning.
                    self.counters.signature_rejected += 1
                    log = logger.warning if self.counters.signature_rejected == 1 else logger.debug
                    log("rejected an unsigned, replayed or wrongly signed MAVLink command")
                    continue
                self._count_bad(len(msg.data), _garbage_kind(msg.reason), msg.reason)
                if msg.reason != "Bad prefix" and len(msg.data) > 1:
                    # pymavlink skipped a whole frame's length; a real frame may start inside those bytes
                    # (a stray 0xFD in garbage looks like a start marker), so rescan them from byte 1.
                    pending = bytes(msg.data[1:]) + bytes(self._mav.buf[self._mav.buf_index :])
                    self.counters.bad_bytes -= len(msg.data) - 1  # those bytes get a second look
                    self._mav = self._new_mavlink_keeping_sequence()
                continue
            # A bogus header naming a msgid this dialect does not know cannot be CRC-checked: pymavlink
            # reports it as MAVLink_unknown, and we record it as such, like any real unknown message.
            messages.append(msg)
            if not self._mav.buf_len():
                # Nothing left to parse (the usual end of a read: whole frames). Asking again would only
                # return None; a partial frame left over is asked for above and stays buffered.
                break
        return messages

    def _decode_whole_frames(self, data: bytes, messages: list[Any]) -> int:
        """Decode the whole unsigned MAVLink 2 frames at the start of ``data`` into ``messages``; return
        how many bytes they took.

        pymavlink's ``parse_char`` finds a frame's end from its header (start marker, payload length, the
        signed flag) and hands it to ``MAVLink.decode``, which checks the length, the CRC and the fields;
        here the same header bytes find each end and ``decode`` is asked directly, a Python call per frame
        instead of three (about a fifth of a frame's parse), through ``decode_unsigned_v2``, which builds
        the message of a plain one (no arrays, no text: all the simulated autopilot sends) itself, from
        pymavlink's message class, struct and CRC, at about a third of ``decode``'s work. It stops, leaving
        the rest to ``parse_char``, at the first byte that is not the start of such a frame (noise, MAVLink
        1, a signed or unknown incompat flag), at a frame cut short, and at one ``decode`` refuses:
        ``parse_char`` then meets exactly what it would have met after the frames before, from the same
        empty buffer, and reports it as always (a frame is decoded twice only when it is refused). Only
        for a link without signing: ``decode`` checks a signature against the replay guard, which must see
        each frame once.
        """
        buf = bytearray(data)  # decode wants a bytearray (it appends the CRC extra to a slice)
        size = len(buf)
        start = 0
        decode = self._mav.decode
        while start + 3 <= size and buf[start] == mavlink2.PROTOCOL_MARKER_V2 and buf[start + 2] == 0:
            end = start + V2_FRAME_OVERHEAD + buf[start + 1]
            if end > size:
                break
            try:
                msg = decode_unsigned_v2(buf[start:end], decode)
            except (mavlink2.MAVError, struct.error, ValueError, IndexError):
                break
            messages.append(msg)
            start = end
        return start

    def _new_mavlink_keeping_sequence(self) -> mavlink2.MAVLink:
        seq = self._mav.seq
        mav = self._new_mavlink()
        mav.seq = seq
        return mav

    def _drop_partial_frame(self) -> None:
        """Count what the parser holds of an unfinished frame as truncated, and start afresh."""
        left = len(self._mav.buf) - self._mav.buf_index
        if left > 0:
            self._count_bad(left, "truncated", "frame cut short")
            self._mav = self._new_mavlink_keeping_sequence()

    def _count_bad(self, n_bytes: int, kind: str, reason: str) -> None:
        """``n_bytes`` skipped: a run of noise (``kind`` "noise") or one bad frame of ``kind`` (the
        ``MavlinkCounters`` field bad_crc, bad_header or truncated)."""
        counters = self.counters
        counters.bad_bytes += n_bytes
        if kind == "noise":
            counters.noise_bytes += n_bytes
        else:
            counters.bad_frames += 1
            setattr(counters, kind, getattr(counters, kind) + 1)
        logger.debug("skipped %d bad MAVLink bytes: %s", n_bytes, reason)

    def _new_converters(self) -> dict[str, Callable[[Any, int], Reading | None]]:
        """What to make of each message we read, by its name (one look-up per frame, not a chain of
        comparisons); a message not named here is recorded on mavlink/raw and nothing more."""
        return {
            "GPS_RAW_INT": self._convert_gps,
            "HIGHRES_IMU": self._convert_highres_imu,
            "SCALED_IMU": self._convert_scaled_imu,
            "RAW_IMU": self._convert_scaled_imu,
            "SYS_STATUS": _sys_status,
            "BATTERY_STATUS": _battery_status,
            "ATTITUDE": _attitude,
            "HEARTBEAT": self._convert_heartbeat,
            "OBSTACLE_DISTANCE": self._convert_scan,
            "DISTANCE_SENSOR": self._convert_beam,
        }

    def _convert_scan(self, msg: Any, t_ns: int) -> ObstacleScan | None:
        try:
            scan = read_scan(msg, t_ns)
        except ScanRejected as error:
            self._refuse_range_reading("OBSTACLE_DISTANCE", "scans_rejected", error)
            return None
        self.counters.scans += 1
        return scan

    def _convert_beam(self, msg: Any, t_ns: int) -> RangeBeam | None:
        counters = self.counters
        try:
            beam = read_beam(msg, t_ns)
        except BeamRejected as error:
            self._refuse_range_reading("DISTANCE_SENSOR", "beams_rejected", error)
            return None
        if beam is None:
            counters.beams_unused += 1  # looking up or down: not an obstacle sensor
            return None
        counters.beams += 1
        return beam

    def _refuse_range_reading(self, name: str, counter: str, error: ValueError) -> None:
        """A range sensor's message that cannot be read: counted under ``counter`` and logged (the first,
        then every 100th), never raised: a driver's bad message must not stop the rover loop."""
        refused = getattr(self.counters, counter) + 1
        setattr(self.counters, counter, refused)
        if refused == 1 or refused % _LOG_REJECTED_RANGE_EVERY == 0:
            logger.warning("%s refused (%d so far): %s", name, refused, error)

    def _convert_gps(self, msg: Any, t_ns: int) -> GpsFix:
        fix = _gps_fix(msg, t_ns)
        self._publish_gps(fix)
        return fix

    def _convert_highres_imu(self, msg: Any, t_ns: int) -> ImuSample:
        # Already SI (m/s^2, rad/s), FRD.
        sample = ImuSample(t_ns, (msg.xgyro, -msg.ygyro, -msg.zgyro), (msg.xacc, -msg.yacc, -msg.zacc))
        self._publish_imu(sample)
        return sample

    def _convert_scaled_imu(self, msg: Any, t_ns: int) -> ImuSample:
        # SCALED_IMU and RAW_IMU: mrad/s and mG, FRD.
        sample = ImuSample(
            t_ns,
            (msg.xgyro * _MRAD_TO_RAD, -msg.ygyro * _MRAD_TO_RAD, -msg.zgyro * _MRAD_TO_RAD),
            (msg.xacc * _MG_TO_MPS2, -msg.yacc * _MG_TO_MPS2, -msg.zacc * _MG_TO_MPS2),
        )
        self._publish_imu(sample)
        return sample

    def _convert_heartbeat(self, msg: Any, t_ns: int) -> None:
        if msg.autopilot != mavlink2.MAV_AUTOPILOT_INVALID:
            # Companions and ground stations announce MAV_AUTOPILOT_INVALID; anything else is an autopilot.
            self.last_heartbeat_ns = t_ns

    def _publish_gps(self, fix: GpsFix) -> None:
        if math.isnan(fix.eph_m):
            covariance = [0.0] * 9
            covariance_type = _COVARIANCE_UNKNOWN
        else:
            horizontal, vertical = fix.eph_m**2, (2.0 * fix.eph_m) ** 2
            covariance = [horizontal, 0.0, 0.0, 0.0, horizontal, 0.0, 0.0, 0.0, vertical]
            covariance_type = _COVARIANCE_DIAGONAL_KNOWN
        self._sink.publish(
            SENSORS_GPS,
            fix.t_ns,
            {
                "timestamp": stamp(fix.t_ns),
                "frame_id": _GPS_FRAME_ID,
                "latitude": fix.lat_deg,
                "longitude": fix.lon_deg,
                "altitude": fix.alt_m,
                "position_covariance": covariance,
                "position_covariance_type": covariance_type,
                "fix_type": fix.fix_type,
                "satellites": fix.satellites,
                "eph_m": fix.eph_m,
            },
        )

    def _publish_imu(self, sample: ImuSample) -> None:
        gx, gy, gz = sample.gyro_xyz_rps
        ax, ay, az = sample.accel_xyz_mps2
        self._sink.publish(
            SENSORS_IMU,
            sample.t_ns,
            {
                "timestamp": stamp(sample.t_ns),
                "frame_id": _IMU_FRAME_ID,
                "angular_velocity": {"x": gx, "y": gy, "z": gz},
                "linear_acceleration": {"x": ax, "y": ay, "z": az},
            },
        )

    # --- lifetime ------------------------------------------------------------------------------
    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._transport.close()


# The dialect's message names: capitals, digits and underscores, so JSON needs no escapes for them (a test
# checks). A name outside it (UNKNOWN_<id> of a message the dialect does not know) is encoded as a dict.
_DIALECT_NAMES = frozenset(message.msgname for message in mavlink2.mavlink_map.values())


def _raw_record(
    t_ns: int, direction: str, msgid: int, name: str, sysid: int, compid: int, data: str
) -> dict[str, object]:
    """A frame's mavlink/raw record (``data``: the frame in base64)."""
    return {
        "timestamp": stamp(t_ns),
        "direction": direction,
        "msgid": msgid,
        "name": name,
        "sysid": sysid,
        "compid": compid,
        "data": data,
    }


def _raw_json(t_ns: int, direction: str, msgid: int, name: str, sysid: int, compid: int, data: str) -> bytes:
    """``encode_message(_raw_record(...))``, formatted directly.

    Hot path: every frame in both directions is recorded (~70 per simulated second), and its fields are
    integers and text that JSON needs no escapes for (a dialect name, "rx"/"tx", base64), so one format
    call gives the JSON encoder's bytes without the dict (a test compares them on random frames)."""
    sec, nsec = divmod(t_ns, 1_000_000_000)
    return (
        f'{{"timestamp":{{"sec":{sec},"nsec":{nsec}}},"direction":"{direction}","msgid":{msgid},'
        f'"name":"{name}","sysid":{sysid},"compid":{compid},"data":"{data}"}}'
    ).encode()


def _allow_unsigned(_mav: Any, msgid: int) -> bool:
    return msgid not in _SIGNED_ONLY


_SIGNED_ONLY = frozenset(
    {
        mavlink2.MAVLINK_MSG_ID_COMMAND_INT,
        mavlink2.MAVLINK_MSG_ID_COMMAND_LONG,
        mavlink2.MAVLINK_MSG_ID_SET_POSITION_TARGET_GLOBAL_INT,
        *MISSION_MESSAGE_IDS,  # firmware_bridge.mavlink_mission: why
    }
)


def _src(msg: Any) -> tuple[int, int]:
    return msg.get_srcSystem(), msg.get_srcComponent()


def _unknown_if(value: int, scale: float) -> float:
    return math.nan if value == _UINT16_UNKNOWN else value * scale


def _sys_status(msg: Any, t_ns: int) -> BatteryState:
    current = math.nan if msg.current_battery == -1 else msg.current_battery * 0.01
    voltage = math.nan if msg.voltage_battery == _UINT16_UNKNOWN else msg.voltage_battery * 1e-3
    return BatteryState(t_ns, voltage, current, int(msg.battery_remaining), "SYS_STATUS")


def _battery_status(msg: Any, t_ns: int) -> BatteryState:
    cells = [v for v in msg.voltages if v != _UINT16_UNKNOWN]
    current = math.nan if msg.current_battery == -1 else msg.current_battery * 0.01
    return BatteryState(
        t_ns, sum(cells) * 1e-3 if cells else math.nan, current, int(msg.battery_remaining), "BATTERY_STATUS"
    )


def _attitude(msg: Any, t_ns: int) -> AttitudeSample:
    yaw = math.pi / 2.0 - msg.yaw
    # An infinite yaw (an AHRS that overflowed) is no angle: unknown, like any value we cannot use, and
    # math.sin would raise on it.
    wrapped = math.atan2(math.sin(yaw), math.cos(yaw)) if math.isfinite(yaw) else math.nan
    return AttitudeSample(t_ns, msg.roll, msg.pitch, wrapped)


def _gps_fix(msg: Any, t_ns: int) -> GpsFix:
    cog = msg.cog
    return GpsFix(
        t_ns=t_ns,
        lat_deg=msg.lat * 1e-7,
        lon_deg=msg.lon * 1e-7,
        alt_m=msg.alt * 1e-3,
        fix_type=int(msg.fix_type),
        satellites=int(msg.satellites_visible),
        eph_m=_unknown_if(msg.eph, 0.01),
        speed_mps=_unknown_if(msg.vel, 0.01),
        course_rad=math.nan if cog == _UINT16_UNKNOWN else compass_to_enu_rad(cog * 0.01),
    )
