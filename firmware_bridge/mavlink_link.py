"""The companion's MAVLink 2 link to the autopilot: heartbeats out, GPS and IMU in, every frame recorded.

MAVLink reports the IMU in the body frame x forward, y right, z down (FRD); our ``sensors/imu`` topic
and ``ImuSample`` use x forward, y left, z up (FLU), so y and z change sign here, once.
"""

from __future__ import annotations

import base64
import logging
import math
import struct
from dataclasses import asdict, dataclass
from types import TracebackType
from typing import Any

from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.errors import BridgeOperationError
from firmware_bridge.mavlink_transport import Transport
from logs.clock import Clock
from logs.settings import Table
from logs.sink import MessageSink
from logs.topics import MAVLINK_RAW, SENSORS_GPS, SENSORS_IMU, stamp

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

    @classmethod
    def from_table(cls, table: Table) -> MavlinkConfig:
        """Keys: connection, system_id, component_id, autopilot_system_id, allow_remote (all optional)."""
        d = cls()
        config = cls(
            connection=table.text("connection", d.connection),
            system_id=table.integer("system_id", d.system_id, lo=1, hi=255),
            component_id=table.integer("component_id", d.component_id, lo=1, hi=255),
            autopilot_system_id=table.integer("autopilot_system_id", d.autopilot_system_id, lo=1, hi=255),
            allow_remote=table.flag("allow_remote", d.allow_remote),
        )
        table.finish()
        return config


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


@dataclass(frozen=True)
class ImuSample:
    """Body-frame (x forward, y left, z up) angular rate in rad/s and specific force in m/s^2."""

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


Reading = GpsFix | ImuSample | AttitudeSample


@dataclass
class MavlinkCounters:
    rx_frames: int = 0
    bad_frames: int = 0
    bad_bytes: int = 0
    tx_frames: int = 0
    tx_errors: int = 0

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


class _TransportFile:
    """The file-like object pymavlink writes packed frames to."""

    def __init__(self, transport: Transport) -> None:
        self._transport = transport

    def write(self, data: bytes) -> None:
        self._transport.write(bytes(data))


def _header_fields(frame: bytes) -> tuple[int, int, int]:
    """(msgid, sysid, compid) straight from a frame's header, for frames pymavlink does not know."""
    if frame[0] == mavlink2.PROTOCOL_MARKER_V2 and len(frame) >= 10:
        return frame[7] | frame[8] << 8 | frame[9] << 16, frame[5], frame[6]
    if len(frame) >= 6:
        return frame[5], frame[3], frame[4]
    return -1, 0, 0


def compass_to_enu_rad(bearing_deg: float) -> float:
    """A compass bearing (degrees clockwise from north) as radians CCW from east, in (-pi, pi]."""
    angle = math.radians(90.0 - bearing_deg)
    return math.atan2(math.sin(angle), math.cos(angle))


class MavlinkLink:
    """Our MAVLink component on the companion computer (``MAV_TYPE_ONBOARD_CONTROLLER``).

    ``autopilot_system_id`` (optional) keeps sensors and heartbeats from other systems out.
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
    ) -> None:
        self._transport = transport
        self._clock = clock
        self._sink = sink
        self.system_id = system_id
        self.component_id = component_id
        self._autopilot_system_id = autopilot_system_id
        self._mav = self._new_mavlink()
        self.counters = MavlinkCounters()
        self.last_heartbeat_ns: int | None = None
        self._closed = False

    def _new_mavlink(self) -> mavlink2.MAVLink:
        mav = mavlink2.MAVLink(_TransportFile(self._transport), self.system_id, self.component_id)
        # Robust parsing turns garbage into BAD_DATA messages instead of exceptions, so we can count it.
        mav.robust_parsing = True
        return mav

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

    def _publish_raw(
        self, t_ns: int, direction: str, frame: bytes, msgid: int, name: str, sysid: int, compid: int
    ) -> None:
        self._sink.publish(
            MAVLINK_RAW,
            t_ns,
            {
                "timestamp": stamp(t_ns),
                "direction": direction,
                "msgid": msgid,
                "name": name,
                "sysid": sysid,
                "compid": compid,
                "data": base64.b64encode(frame).decode("ascii"),
            },
        )

    # --- receiving -----------------------------------------------------------------------------
    def poll(self) -> list[Reading]:
        """Read and parse everything available; return GPS / IMU / attitude readings in arrival order."""
        data = self._transport.read()
        if not data:
            return []
        t_ns = self._clock.now_ns()
        readings: list[Reading] = []
        for msg in self._parse(data):
            frame = bytes(msg.get_msgbuf())
            if isinstance(msg, mavlink2.MAVLink_unknown):
                msgid, sysid, compid = _header_fields(frame)
            else:
                msgid, sysid, compid = msg.get_msgId(), msg.get_srcSystem(), msg.get_srcComponent()
            self.counters.rx_frames += 1
            self._publish_raw(t_ns, "rx", frame, msgid, msg.get_type(), sysid, compid)
            if self._autopilot_system_id is not None and sysid != self._autopilot_system_id:
                continue
            reading = self._convert(msg, t_ns)
            if reading is not None:
                readings.append(reading)
        return readings

    def _parse(self, data: bytes) -> list[Any]:
        messages: list[Any] = []
        pending = data
        while True:
            try:
                msg = self._mav.parse_char(pending)
            except (mavlink2.MAVError, struct.error, ValueError, IndexError) as err:
                # Should not happen with robust parsing; if it does, drop what is buffered and go on.
                self._count_bad(len(self._mav.buf) - self._mav.buf_index, str(err))
                self._mav = self._new_mavlink_keeping_sequence()
                break
            pending = b""
            if msg is None:
                break
            if isinstance(msg, mavlink2.MAVLink_bad_data):
                self._count_bad(len(msg.data), msg.reason)
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
        return messages

    def _new_mavlink_keeping_sequence(self) -> mavlink2.MAVLink:
        seq = self._mav.seq
        mav = self._new_mavlink()
        mav.seq = seq
        return mav

    def _count_bad(self, n_bytes: int, reason: str) -> None:
        self.counters.bad_frames += 1
        self.counters.bad_bytes += n_bytes
        logger.debug("skipped %d bad MAVLink bytes: %s", n_bytes, reason)

    def _convert(self, msg: Any, t_ns: int) -> Reading | None:
        kind = msg.get_type()
        if kind == "GPS_RAW_INT":
            fix = _gps_fix(msg, t_ns)
            self._publish_gps(fix)
            return fix
        if kind in ("SCALED_IMU", "RAW_IMU"):
            sample = ImuSample(
                t_ns,
                (msg.xgyro * _MRAD_TO_RAD, -msg.ygyro * _MRAD_TO_RAD, -msg.zgyro * _MRAD_TO_RAD),
                (msg.xacc * _MG_TO_MPS2, -msg.yacc * _MG_TO_MPS2, -msg.zacc * _MG_TO_MPS2),
            )
            self._publish_imu(sample)
            return sample
        if kind == "ATTITUDE":
            yaw = math.pi / 2.0 - msg.yaw
            return AttitudeSample(t_ns, msg.roll, msg.pitch, math.atan2(math.sin(yaw), math.cos(yaw)))
        if kind == "HEARTBEAT" and msg.autopilot != mavlink2.MAV_AUTOPILOT_INVALID:
            # Companions and ground stations announce MAV_AUTOPILOT_INVALID; anything else is an autopilot.
            self.last_heartbeat_ns = t_ns
        return None

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

    def __enter__(self) -> MavlinkLink:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def _unknown_if(value: int, scale: float) -> float:
    return math.nan if value == _UINT16_UNKNOWN else value * scale


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
