import base64
import math
import re

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.errors import BridgeSetupError
from firmware_bridge.mavlink_link import (
    AttitudeSample,
    GpsFix,
    ImuSample,
    MavlinkConfig,
    MavlinkLink,
    compass_to_enu_rad,
)
from firmware_bridge.mavlink_transport import UdpTransport, memory_pipe_pair, open_transport
from logs.clock import SimClock
from logs.settings import ConfigError, parse_toml
from logs.sink import MemorySink
from logs.topics import MAVLINK_RAW, SENSORS_GPS, SENSORS_IMU


def autopilot_frames(*messages: mavlink2.MAVLink_message) -> bytes:
    mav = mavlink2.MAVLink(None, 1, 1)
    return b"".join(bytes(m.pack(mav)) for m in messages)


def gps_msg(lat=473977420, lon=85455940, alt=488000, eph=150, vel=250, cog=9000, fix=3, sats=12):
    return mavlink2.MAVLink_gps_raw_int_message(1_000_000, fix, lat, lon, alt, eph, 300, vel, cog, sats)


def test_gps_raw_int_is_converted_and_published():
    companion_end, autopilot_end = memory_pipe_pair()
    sink = MemorySink()
    link = MavlinkLink(companion_end, SimClock(2_000_000_000), sink)
    autopilot_end.write(autopilot_frames(gps_msg()))
    (fix,) = link.poll()
    assert isinstance(fix, GpsFix)
    assert fix.t_ns == 2_000_000_000
    assert fix.lat_deg == pytest.approx(47.397742)
    assert fix.lon_deg == pytest.approx(8.545594)
    assert fix.alt_m == pytest.approx(488.0)
    assert fix.eph_m == pytest.approx(1.5)
    assert fix.speed_mps == pytest.approx(2.5)
    assert fix.course_rad == pytest.approx(0.0)  # compass 90 deg = east = 0 rad in ENU
    (published,) = sink.on(SENSORS_GPS)
    assert published["position_covariance_type"] == 2
    assert published["position_covariance"][0] == pytest.approx(1.5**2)
    assert published["position_covariance"][4] == pytest.approx(1.5**2)
    assert published["position_covariance"][8] == pytest.approx(3.0**2)
    assert published["latitude"] == fix.lat_deg


def test_unknown_and_out_of_range_gps_values_pass_through():
    companion_end, autopilot_end = memory_pipe_pair()
    sink = MemorySink()
    link = MavlinkLink(companion_end, SimClock(), sink)
    autopilot_end.write(autopilot_frames(gps_msg(lat=950000000, eph=65535, vel=65535, cog=65535, fix=0)))
    (fix,) = link.poll()
    assert fix.lat_deg == pytest.approx(95.0)
    assert fix.fix_type == 0
    assert math.isnan(fix.eph_m) and math.isnan(fix.speed_mps) and math.isnan(fix.course_rad)
    assert sink.on(SENSORS_GPS)[0]["position_covariance_type"] == 0


@pytest.mark.parametrize("yaw", [math.inf, -math.inf, math.nan])
def test_an_attitude_with_a_yaw_that_is_no_angle_passes_through_as_unknown(yaw):
    # An AHRS that overflowed sends yaw = inf in a well-formed ATTITUDE: wrapping it raised ValueError out
    # of poll(), and out of the rover's control tick. Like other values the link cannot use, it passes
    # through as unknown (NaN), for the estimator to count and refuse; what follows is still read.
    companion_end, autopilot_end = memory_pipe_pair()
    link = MavlinkLink(companion_end, SimClock(), MemorySink())
    attitude = mavlink2.MAVLink_attitude_message(0, 0.1, -0.2, yaw, 0.0, 0.0, 0.0)
    autopilot_end.write(autopilot_frames(attitude, gps_msg()))
    sample, fix = link.poll()
    assert isinstance(sample, AttitudeSample)
    assert math.isnan(sample.yaw_rad)
    assert (sample.roll_rad, sample.pitch_rad) == pytest.approx((0.1, -0.2))
    assert isinstance(fix, GpsFix)


def test_scaled_and_raw_imu_become_flu_si_units():
    companion_end, autopilot_end = memory_pipe_pair()
    sink = MemorySink()
    link = MavlinkLink(companion_end, SimClock(), sink)
    # FRD on the wire: resting level, turning left (CCW) at 0.1 rad/s => zgyro = -100 mrad/s, zacc = -1000 mG
    scaled = mavlink2.MAVLink_scaled_imu_message(10, 100, 50, -1000, 1, 2, -100, 0, 0, 0, 0)
    raw = mavlink2.MAVLink_raw_imu_message(10, 0, 0, -1000, 0, 0, 0, 0, 0, 0, 0, 0)
    autopilot_end.write(autopilot_frames(scaled, raw))
    first, second = link.poll()
    assert isinstance(first, ImuSample) and isinstance(second, ImuSample)
    assert first.gyro_xyz_rps == pytest.approx((0.001, -0.002, 0.1))
    assert first.accel_xyz_mps2 == pytest.approx((0.980665, -0.4903325, 9.80665))
    assert second.accel_xyz_mps2 == pytest.approx((0.0, 0.0, 9.80665))
    imu = sink.on(SENSORS_IMU)[0]
    assert imu["angular_velocity"]["z"] == pytest.approx(0.1)
    assert imu["linear_acceleration"]["z"] == pytest.approx(9.80665)


@pytest.mark.parametrize(
    "garbage",
    [
        b"\x00\x01\x02hello\xff" * 3,
        # a stray start marker (0xFD, length 16, msgid 0) makes pymavlink swallow a frame's length of
        # bytes, which fails the CRC; the link rescans them and finds the real frame inside
        b"\x13\x37\xfd\x10\x00\x00\x01\x02\x03\x00\x00\x00\x05\x06",
    ],
)
def test_garbage_before_a_valid_frame_is_counted_and_the_frame_still_delivered(garbage):
    companion_end, autopilot_end = memory_pipe_pair()
    link = MavlinkLink(companion_end, SimClock(), MemorySink())
    scaled = mavlink2.MAVLink_scaled_imu_message(10, 0, 0, -1000, 0, 0, 0, 0, 0, 0, 0)
    autopilot_end.write(garbage + autopilot_frames(gps_msg(), scaled))
    readings = link.poll()
    assert [type(r) for r in readings] == [GpsFix, ImuSample]
    # Every garbage byte skipped once, whether as noise between frames or inside a bad frame.
    assert link.counters.bad_bytes == len(garbage)
    assert link.counters.rx_frames == 2


def test_corrupted_crc_frame_is_skipped_and_next_frame_delivered():
    companion_end, autopilot_end = memory_pipe_pair()
    link = MavlinkLink(companion_end, SimClock(), MemorySink())
    bad = bytearray(autopilot_frames(gps_msg()))
    bad[-1] ^= 0xFF
    autopilot_end.write(bytes(bad) + autopilot_frames(gps_msg(lat=1)))
    readings = link.poll()
    assert len(readings) == 1 and readings[0].lat_deg == pytest.approx(1e-7)
    assert link.counters.bad_frames >= 1


def test_frames_split_across_reads_are_reassembled():
    companion_end, autopilot_end = memory_pipe_pair()
    link = MavlinkLink(companion_end, SimClock(), MemorySink())
    data = autopilot_frames(gps_msg())
    autopilot_end.write(data[:7])
    assert link.poll() == []
    autopilot_end.write(data[7:])
    assert len(link.poll()) == 1


def test_heartbeat_is_sent_recorded_and_autopilot_heartbeat_remembered():
    companion_end, autopilot_end = memory_pipe_pair()
    clock, sink = SimClock(7), MemorySink()
    link = MavlinkLink(companion_end, clock, sink, system_id=1, component_id=191)
    link.send_heartbeat()
    wire = autopilot_end.read()
    (heartbeat,) = mavlink2.MAVLink(None).parse_buffer(wire)
    assert heartbeat.get_type() == "HEARTBEAT"
    assert heartbeat.type == mavlink2.MAV_TYPE_ONBOARD_CONTROLLER
    assert heartbeat.get_srcComponent() == 191
    (record,) = sink.on(MAVLINK_RAW)
    assert record["direction"] == "tx" and record["name"] == "HEARTBEAT" and record["compid"] == 191
    assert base64.b64decode(record["data"]) == wire
    assert link.last_heartbeat_ns is None
    autopilot_end.write(
        autopilot_frames(
            mavlink2.MAVLink_heartbeat_message(
                mavlink2.MAV_TYPE_GROUND_ROVER, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4, 3
            )
        )
    )
    assert link.poll() == []
    assert link.last_heartbeat_ns == 7
    assert link.counters.tx_frames == 1 and link.counters.rx_frames == 1


def test_link_close_is_idempotent_and_context_managed():
    companion_end, _ = memory_pipe_pair()
    with MavlinkLink(companion_end, SimClock(), MemorySink()) as link:
        pass
    link.close()
    assert link.poll() == []


def test_udp_loopback_round_trip_with_os_chosen_port():
    server = open_transport("udpin:127.0.0.1:0")
    assert isinstance(server, UdpTransport)
    host, port = server.local_address
    client = open_transport(f"udpout:{host}:{port}")
    try:
        server.write(b"nobody yet")  # udpin has no peer until someone writes: dropped, not raised
        assert server.dropped_writes == 1
        client.write(b"ping")
        for _ in range(1000):
            data = server.read()
            if data:
                break
        assert data == b"ping"
        server.write(b"pong")
        for _ in range(1000):
            reply = client.read()
            if reply:
                break
        assert reply == b"pong"
    finally:
        client.close()
        server.close()
        server.close()


# The non-loopback hosts below are refused by the loopback guard before any socket exists: nothing is sent.
@pytest.mark.parametrize(
    ("connection", "text"),
    [
        ("memory", "memory_pipe_pair"),
        ("udpout:10.0.0.1:14550", "loopback"),
        ("udpin:0.0.0.0:14550", "loopback"),
        ("udpout:example.com:14550", "loopback"),
        ("udpout:127.0.0.1", "HOST:PORT"),
        ("tcp:10.0.0.1:5760", "loopback"),
        ("tcp:127.0.0.1:0", "out of range"),
        ("serial:/dev/ttyUSB0:fast", "not a number"),
        ("/dev/no-such-tty-for-rover,57600", "cannot open"),
        ("serial:/dev/null:57600", "not a serial device"),
        ("serial:/dev/null:12345", "baud"),
        ("serial:/dev/null:0", "baud 0 is not a rate"),
        ("carrier-pigeon", "unknown MAVLink connection"),
    ],
)
def test_open_transport_refuses_what_it_cannot_or_must_not_open(connection, text):
    with pytest.raises(BridgeSetupError, match=text):
        open_transport(connection)


def test_mavlink_config_from_table():
    config = MavlinkConfig.from_table(parse_toml('connection = "udpin:127.0.0.1:0"', "rover.toml"))
    assert config == MavlinkConfig(connection="udpin:127.0.0.1:0")
    with pytest.raises(ConfigError, match="system_id"):
        MavlinkConfig.from_table(parse_toml("system_id = 0", "rover.toml"))


@pytest.mark.parametrize(
    ("connection", "text"),
    [
        ("udpin:127.0.0.1", "must look like udpin:HOST:PORT"),
        ("udpout:127.0.0.1:99999", "port 99999 is out of range"),
        ("tcp:127.0.0.1:0", "port 0 is out of range"),
        ("udpout:192.0.2.7:14550", "not a loopback"),
        ("serial:/dev/ttyS0:fast", "baud 'fast' is not a number"),
        # termios has B0, but it is no rate: it hangs the line up, and the autopilot is never heard.
        ("serial:/dev/ttyAMA0:0", "baud 0 is not a rate (B0 hangs the line up)"),
        ("/dev/ttyACM0,0", "baud 0 is not a rate"),
        ("udp:127.0.0.1:14550", "unknown MAVLink connection"),
        ("", "unknown MAVLink connection"),
    ],
)
def test_mavlink_config_names_a_bad_connection_string_at_load(connection, text):
    # A typo in the connection is a config error naming the file and key, found before anything opens.
    with pytest.raises(ConfigError, match=rf"rover\.toml: connection: .*{re.escape(text)}"):
        MavlinkConfig.from_table(parse_toml(f'connection = "{connection}"', "rover.toml"))


@pytest.mark.parametrize(
    "connection", ["memory", "udpin:127.0.0.1:0", "tcp:localhost:5760", "/dev/ttyACM0,57600", "serial:/dev/x"]
)
def test_mavlink_config_takes_a_well_formed_connection_without_opening_it(connection):
    assert (
        MavlinkConfig.from_table(parse_toml(f'connection = "{connection}"', "rover.toml")).connection
        == connection
    )


def test_mavlink_config_takes_a_remote_host_only_with_allow_remote():
    text = 'connection = "udpout:192.0.2.7:14550"\nallow_remote = true'
    assert MavlinkConfig.from_table(parse_toml(text, "rover.toml")).allow_remote


def test_compass_to_enu():
    assert compass_to_enu_rad(0.0) == pytest.approx(math.pi / 2)
    assert compass_to_enu_rad(90.0) == pytest.approx(0.0)
    assert compass_to_enu_rad(180.0) == pytest.approx(-math.pi / 2)
