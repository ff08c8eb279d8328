"""A simulated autopilot: the rover's MAVLink 2 peer in HIL, reporting GPS and IMU from the true state.

It speaks MAVLink's conventions on the wire: HEARTBEAT as a ground rover, SYS_STATUS with the battery,
GPS_RAW_INT in degE7 / mm / cm / cdeg (course as a compass
bearing), SCALED_IMU in mrad/s and mG in the FRD body frame (x forward, y right, z down). The truth it is
given uses ours: ENU metres, yaw counter-clockwise from east, FLU body axes.
"""

from __future__ import annotations

import logging
import math
from typing import Any, NamedTuple

import numpy as np
import pymap3d
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.errors import BridgeOperationError
from firmware_bridge.mavlink_frames import send_unsigned_v2
from firmware_bridge.mavlink_transport import Transport
from hil.faults import FaultSchedule
from hil.first_sample import first_sample_withheld
from hil.sensors import GpsModel, GpsSample, ImuModel, course_over_ground_deg, ground_speed_mps
from logs.clock import Clock, to_ns

logger = logging.getLogger(__name__)

_MPS2_TO_MG = 1000.0 / 9.80665
_RAD_TO_MRAD = 1000.0
_INT16_MAX = 32767
_UINT16_KNOWN_MAX = 65534  # 65535 means "unknown" in GPS_RAW_INT
# Named explicitly (pymap3d's default when given none, as the GPS fixes used before): the datum's ECEF
# position is computed with it once and the fixes go back to geodetic with it.
_WGS84 = pymap3d.Ellipsoid.from_name("wgs84")
_SENSORS_PRESENT = (
    mavlink2.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mavlink2.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mavlink2.MAV_SYS_STATUS_SENSOR_GPS
    | mavlink2.MAV_SYS_STATUS_SENSOR_BATTERY
)


class AutopilotTruth(NamedTuple):
    """The true state the autopilot's sensors measure (ENU metres, radians CCW from east, FLU body axes).

    ``accel_body_mps2`` is specific force as an IMU measures it: at rest on level ground (0, 0, +9.81).
    A NamedTuple: the world builds one every physics tick, and a frozen dataclass cost twice as much.
    """

    x_m: float
    y_m: float
    z_m: float
    yaw_rad: float
    speed_mps: float
    yaw_rate_rps: float
    accel_body_mps2: tuple[float, float, float]
    roll_rad: float = 0.0
    pitch_rad: float = 0.0  # nose up positive, as MAVLink's ATTITUDE
    battery_voltage_v: float = 0.0
    battery_current_a: float = 0.0
    battery_remaining_pct: int = -1  # -1: unknown, as in SYS_STATUS
    lateral_speed_mps: float = 0.0  # the body's sideways slide (y left): the GPS's ground track has it


def _int16(value: float) -> int:
    """``value`` rounded into a symmetric int16 field (six per IMU sample: a comparison, not min/max)."""
    rounded = round(value)
    if -_INT16_MAX <= rounded <= _INT16_MAX:
        return rounded
    return _INT16_MAX if rounded > 0 else -_INT16_MAX


class SimAutopilot:
    """Sends HEARTBEAT, SYS_STATUS, GPS_RAW_INT, SCALED_IMU and ATTITUDE at their rates, on the clock.

    ``gps`` and ``imu`` are the sensor models (``hil.sensors``); by default fault-free ones built from the
    noise figures. Call ``step(truth)`` every physics tick: the GPS's latency and delay faults look back
    at the truth of earlier ticks.
    """

    def __init__(
        self,
        transport: Transport,
        clock: Clock,
        rng: np.random.Generator,
        *,
        datum_lat_deg: float,
        datum_lon_deg: float,
        datum_alt_m: float,
        gps_rate_hz: float = 5.0,
        imu_rate_hz: float = 50.0,
        attitude_rate_hz: float = 10.0,
        heartbeat_rate_hz: float = 1.0,
        sys_status_rate_hz: float = 1.0,
        gps_noise_m: float = 0.5,
        gyro_noise_rps: float = 0.005,
        accel_noise_mps2: float = 0.05,
        heading_noise_rad: float = 0.035,
        system_id: int = 1,
        component_id: int = 1,
        gps: GpsModel | None = None,
        imu: ImuModel | None = None,
    ) -> None:
        for name, rate in (
            ("sys_status_rate_hz", sys_status_rate_hz),
            ("gps_rate_hz", gps_rate_hz),
            ("imu_rate_hz", imu_rate_hz),
            ("attitude_rate_hz", attitude_rate_hz),
            ("heartbeat_rate_hz", heartbeat_rate_hz),
        ):
            if not (math.isfinite(rate) and rate > 0):
                raise ValueError(f"SimAutopilot {name} must be a positive number, got {rate}")
        for name, sigma in (
            ("gps_noise_m", gps_noise_m),
            ("gyro_noise_rps", gyro_noise_rps),
            ("accel_noise_mps2", accel_noise_mps2),
            ("heading_noise_rad", heading_noise_rad),
        ):
            if not (math.isfinite(sigma) and sigma >= 0):
                raise ValueError(f"SimAutopilot {name} must be >= 0, got {sigma}")
        self._transport = transport
        self._clock = clock
        self._rng = rng
        self._datum = (datum_lat_deg, datum_lon_deg, datum_alt_m)
        self._datum_ecef = pymap3d.geodetic2ecef(datum_lat_deg, datum_lon_deg, datum_alt_m, _WGS84, deg=True)
        self._gps_noise_m = gps_noise_m
        self._gyro_noise_rps = gyro_noise_rps
        self._accel_noise_mps2 = accel_noise_mps2
        self._heading_noise_rad = heading_noise_rad
        # pymavlink writes each packed frame (bytes) to its "file": the transport takes them as they are.
        self._mav = mavlink2.MAVLink(transport, system_id, component_id)
        self._mav.robust_parsing = True
        # SCALED_IMU's magnetometer (and temperature) fields stay 0: the simulated IMU has none.
        self._imu_msg = self._mav.scaled_imu_encode(0, 0, 0, 0, 0, 0, 0, 0, 0, 0)
        self._gps = gps or GpsModel(rng, FaultSchedule(), noise_m=gps_noise_m)
        self._imu = imu or ImuModel(
            rng, FaultSchedule(), gyro_noise_rps=gyro_noise_rps, accel_noise_mps2=accel_noise_mps2
        )
        self._periods_ns = {
            "heartbeat": to_ns(1.0 / heartbeat_rate_hz),
            "sys_status": to_ns(1.0 / sys_status_rate_hz),
            "gps": to_ns(1.0 / gps_rate_hz),
            "imu": to_ns(1.0 / imu_rate_hz),
            "attitude": to_ns(1.0 / attitude_rate_hz),
        }
        now = clock.now_ns()
        # Every stream's cadence counts from here; its first sample is due now (see _start for a first step
        # that comes later).
        self._next_ns = dict.fromkeys(self._periods_ns, now)
        self._next_any_ns = now  # the earliest of _next_ns: before it, a step has nothing to send
        self._started = False
        self._withheld: frozenset[str] = frozenset()  # streams whose sample this step takes but not sends
        # Before this clock reading a step would neither send nor remember anything (step's docstring).
        self.next_truth_ns = now
        self.sent: dict[str, int] = dict.fromkeys(self._periods_ns, 0)
        self.send_errors = 0
        self.heartbeats_received = 0
        self.last_heartbeat: Any = None
        self.bad_frames_received = 0

    # --- sending -------------------------------------------------------------------------------
    def _record(self, now: int, truth: AutopilotTruth) -> None:
        """Let the GPS remember where the rover was at ``now`` (for its latency and delay faults)."""
        self._gps.record(
            GpsSample(
                now,
                truth.x_m,
                truth.y_m,
                truth.z_m,
                truth.yaw_rad,
                truth.speed_mps,
                truth.lateral_speed_mps,
                truth.roll_rad,
                truth.pitch_rad,
            )
        )

    def step(self, truth: AutopilotTruth) -> None:
        """Send what is due at the clock's now, in a fixed order: IMU, attitude, GPS, status, heartbeat.

        The GPS remembers ``truth`` for its latency and delay faults. A GPS that never looks back (no
        latency, no delay fault) reads only the truth of a fix's own tick, so only that one is kept: the
        same fixes for a call fewer on most ticks.

        The IMU goes first: it paces the rover's control loop, and a real IMU samples on its own timer;
        behind the GPS fix's geodesy and the other encodings it would leave 0.1-0.3 ms later on the steps
        where those are due, and the loop would take that as period jitter.

        A caller may leave out the steps at clock readings before ``next_truth_ns``: they would send
        nothing and remember nothing (a GPS that looks back keeps it at or before every later tick)."""
        now = self._clock.now_ns()
        if not self._started:
            self._start(now)  # which first samples this step takes without sending
        gps = self._gps
        if gps.looks_back:
            self._record(now, truth)
        if now < self._next_any_ns:
            return  # nothing due (every other physics tick at the default rates: the IMU's is the fastest)
        # One comparison per stream; only a stream that is due is rescheduled (_take_turn).
        due = self._next_ns
        if now >= due["imu"]:
            self._take_turn("imu", now)
            imu = self._imu_message(truth, now)
            if imu is not None:
                self._send("imu", imu)
        if now >= due["attitude"]:
            self._take_turn("attitude", now)
            self._send("attitude", self._attitude_message(truth, now))
        if now >= due["gps"]:
            self._take_turn("gps", now)
            if not gps.looks_back:
                self._record(now, truth)
            fix = self._gps_message(now)
            if fix is not None:
                self._send("gps", fix)
        if now >= due["sys_status"]:
            self._take_turn("sys_status", now)
            self._send("sys_status", self._sys_status_message(truth))
        if now >= due["heartbeat"]:
            self._take_turn("heartbeat", now)
            self._send(
                "heartbeat",
                self._mav.heartbeat_encode(
                    mavlink2.MAV_TYPE_GROUND_ROVER,
                    mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
                    0,
                    0,
                    mavlink2.MAV_STATE_ACTIVE,
                ),
            )
        self._next_any_ns = min(due.values())
        self._withheld = frozenset()  # only the first step withholds
        # A GPS that looks back remembers every tick's truth: it wants the next tick's too (now is before it).
        self.next_truth_ns = now if gps.looks_back else self._next_any_ns

    def send_sensor(self, msg: Any) -> None:
        """Send ``msg`` for a sensor the autopilot reads on its own schedule (its rangefinders'
        DISTANCE_SENSOR, ``hil.rangefinder_sim``): from its system and component, in its sequence, counted
        under the message's name in ``sent``."""
        stream = msg.get_type()
        self.sent.setdefault(stream, 0)
        self._send(stream, msg)

    def _start(self, now: int) -> None:
        """At the first step: a stream whose first sample that step would send half a period late or more,
        but less than a whole one, takes it (its noise drawn) without sending it; its next, on its cadence
        from the start, is its first sent (``hil.first_sample``, the VESCs' rule too).

        ``SimWorld`` makes the autopilot at its epoch and first steps it one physics tick (10 ms) later.
        Sent then, a 50 Hz stream's first sample (the IMU; a GPS at ``gps_rate_hz = 50``) was followed
        10 ms later by its second, on the cadence: the rover's 50 Hz loop took both in its first read and
        recorded two first fixes at the same time. Taken and not sent, as a lost GPS fix still draws its
        noise (``GpsModel.fix``), it leaves every later sample's noise as it was. A slower stream (the 5 Hz
        GPS, heartbeat, status) still sends at the first step, 10 ms late of a period of 100 ms or more:
        what starts the rover. A first step a whole period late or more (the real-time peer's, after its
        warm-up) sends every stream there and resumes from it, as ``_take_turn`` does after a long pause."""
        self._started = True
        self._withheld = frozenset(
            stream
            for stream, due in self._next_ns.items()
            if first_sample_withheld(due, self._periods_ns[stream], now)
        )

    def _take_turn(self, stream: str, now: int) -> None:
        """Schedule ``stream``'s next send after the one due now."""
        following = self._next_ns[stream] + self._periods_ns[stream]
        # Keep the cadence; after a long pause resume from now rather than sending a burst.
        self._next_ns[stream] = following if following > now else now + self._periods_ns[stream]

    def _send(self, stream: str, msg: Any) -> None:
        if stream in self._withheld:
            return  # a first sample a step too late (_start)
        try:
            # mav.send's bytes without its per-frame work for the plain messages all streams send
            # (firmware_bridge.mavlink_frames); the message is not stamped with its frame: nothing reads it.
            send_unsigned_v2(self._mav, msg)
        except (BridgeOperationError, OSError) as err:
            self.send_errors += 1
            logger.debug("simulated autopilot: cannot send %s: %s", msg.get_type(), err)
            return
        self.sent[stream] += 1

    def _gps_message(self, now: int) -> Any:
        fix = self._gps.fix(now)
        if fix is None:
            return None
        lat, lon, alt = self._enu_to_geodetic(fix.x_m, fix.y_m, fix.z_m)
        in_plane = (fix.speed_mps, fix.lateral_speed_mps, fix.roll_rad, fix.pitch_rad)
        eph_cm = min(_UINT16_KNOWN_MAX, round(fix.eph_m * 100.0))
        return self._mav.gps_raw_int_encode(
            now // 1_000,
            fix.fix_type,
            round(float(lat) * 1e7),
            round(float(lon) * 1e7),
            round(float(alt) * 1e3),
            eph_cm,
            min(_UINT16_KNOWN_MAX, eph_cm * 2),
            min(_UINT16_KNOWN_MAX, round(ground_speed_mps(*in_plane) * 100.0)),
            round(course_over_ground_deg(fix.yaw_rad, *in_plane) * 100.0) % 36000,
            fix.satellites,
        )

    def _enu_to_geodetic(self, east_m: float, north_m: float, up_m: float) -> tuple[Any, Any, Any]:
        """``pymap3d.enu2geodetic`` around the datum in its own steps (ENU -> ECEF offset, plus the datum's
        ECEF position, then ``ecef2geodetic``), with the datum's ECEF position computed once rather than on
        every fix: the same pymap3d calls on the same numbers, so the same floats (and GPS bytes)."""
        lat0, lon0, _ = self._datum
        du, dv, dw = pymap3d.enu2uvw(east_m, north_m, up_m, lat0, lon0, deg=True)
        x0, y0, z0 = self._datum_ecef
        return pymap3d.ecef2geodetic(x0 + du, y0 + dv, z0 + dw, _WGS84, deg=True)

    def _sys_status_message(self, truth: AutopilotTruth) -> Any:
        return self._mav.sys_status_encode(
            _SENSORS_PRESENT,
            _SENSORS_PRESENT,
            _SENSORS_PRESENT,
            0,
            max(0, min(65535, round(truth.battery_voltage_v * 1000.0))),
            _battery_centiamps(truth.battery_current_a),
            max(-1, min(100, truth.battery_remaining_pct)),
            0,
            0,
            0,
            0,
            0,
            0,
        )

    def _attitude_message(self, truth: AutopilotTruth, now: int) -> Any:
        # The AHRS heading (compass-aided) wanders by a few degrees; NED yaw is clockwise from north.
        yaw_ned = math.pi / 2.0 - (truth.yaw_rad + float(self._rng.normal(0.0, self._heading_noise_rad)))
        yaw_ned = math.atan2(math.sin(yaw_ned), math.cos(yaw_ned))
        return self._mav.attitude_encode(
            (now // 1_000_000) % (1 << 32),
            truth.roll_rad,
            truth.pitch_rad,  # both conventions: nose up positive, right side down positive roll
            yaw_ned,
            0.0,
            0.0,
            -truth.yaw_rate_rps,
        )

    def _imu_message(self, truth: AutopilotTruth, now: int) -> Any:
        reading = self._imu.read(now, truth.yaw_rate_rps, truth.accel_body_mps2)
        if reading is None:
            return None
        (gx, gy, gz), (ax, ay, az) = reading
        # The one SCALED_IMU message, refilled: 50 a second, and building a pymavlink message object cost
        # a third as much as packing it. Nothing keeps a sent message (the wire gets its packed bytes).
        msg = self._imu_msg
        msg.time_boot_ms = (now // 1_000_000) % (1 << 32)
        # FLU -> FRD: y and z change sign. Rounded, then one range test for all six: a field past int16
        # is rare, so the per-field clamp (_int16) runs only then, not six calls a sample.
        fields: tuple[int, ...] = (
            round(ax * _MPS2_TO_MG),  # xacc
            round(-ay * _MPS2_TO_MG),  # yacc
            round(-az * _MPS2_TO_MG),  # zacc
            round(gx * _RAD_TO_MRAD),  # xgyro
            round(-gy * _RAD_TO_MRAD),  # ygyro
            round(-gz * _RAD_TO_MRAD),  # zgyro
        )
        if not (min(fields) >= -_INT16_MAX and max(fields) <= _INT16_MAX):
            fields = tuple(_int16(field) for field in fields)
        msg.xacc, msg.yacc, msg.zacc, msg.xgyro, msg.ygyro, msg.zgyro = fields
        return msg

    # --- receiving -----------------------------------------------------------------------------
    def poll(self) -> int:
        """Read what the companion sent; count its heartbeats. Returns the number of frames parsed."""
        data = self._transport.read()
        if not data:
            return 0
        count = 0
        pending = data
        while True:
            try:
                msg = self._mav.parse_char(pending)
            except mavlink2.MAVError as err:  # robust parsing should prevent this; never crash the sim
                self.bad_frames_received += 1
                logger.debug("simulated autopilot: unparsable input: %s", err)
                break
            pending = b""
            if msg is None:
                break
            if isinstance(msg, mavlink2.MAVLink_bad_data):
                self.bad_frames_received += 1
                continue
            count += 1
            if msg.get_type() == "HEARTBEAT":
                self.heartbeats_received += 1
                self.last_heartbeat = msg
        return count


def _battery_centiamps(current_a: float) -> int:
    """SYS_STATUS's current_battery (cA): negative while the pack charges (braking motors regenerate), but
    -1 means "not measured" there, so a charge of 0.01 A is sent as 0.02 A."""
    centiamps = max(-_INT16_MAX, min(_INT16_MAX, round(current_a * 100.0)))
    return -2 if centiamps == -1 else centiamps
