import base64
import math

import numpy as np
import pymap3d
import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_link import BatteryState, GpsFix, ImuSample, MavlinkLink
from firmware_bridge.mavlink_transport import memory_pipe_pair
from hil.autopilot_sim import AutopilotTruth, SimAutopilot
from hil.faults import FaultSchedule
from hil.sensors import GpsModel
from logs.clock import SimClock, to_ns
from logs.sink import MemorySink
from logs.topics import MAVLINK_RAW, SENSORS_GPS

DATUM = (47.0, 8.0, 400.0)
DT_S = 0.01


def make_pair(seed=1, **kwargs):
    clock, sink = SimClock(), MemorySink()
    companion_end, autopilot_end = memory_pipe_pair()
    link = MavlinkLink(companion_end, clock, sink)
    sim = SimAutopilot(
        autopilot_end,
        clock,
        np.random.default_rng(seed),
        datum_lat_deg=DATUM[0],
        datum_lon_deg=DATUM[1],
        datum_alt_m=DATUM[2],
        **kwargs,
    )
    return clock, sink, link, sim


def run(clock, link, sim, truth, seconds):
    readings = []
    for _ in range(round(seconds / DT_S)):
        sim.step(truth)
        readings += link.poll()
        clock.advance(to_ns(DT_S))
    return readings


# Driving north-east at 1 m/s (yaw 45 deg CCW from east), turning left at 0.2 rad/s, level.
TRUTH = AutopilotTruth(
    x_m=30.0,
    y_m=-40.0,
    z_m=2.0,
    yaw_rad=math.pi / 4,
    speed_mps=1.0,
    yaw_rate_rps=0.2,
    accel_body_mps2=(0.1, 0.2, 9.80665),
)


def test_gps_and_imu_arrive_at_their_rates_in_our_units():
    clock, sink, link, sim = make_pair(gps_noise_m=0.0, gyro_noise_rps=0.0, accel_noise_mps2=0.0)
    readings = run(clock, link, sim, TRUTH, 1.0)
    fixes = [r for r in readings if isinstance(r, GpsFix)]
    imus = [r for r in readings if isinstance(r, ImuSample)]
    assert len(fixes) == 5
    assert len(imus) == 50
    east, north, up = pymap3d.geodetic2enu(fixes[0].lat_deg, fixes[0].lon_deg, fixes[0].alt_m, *DATUM)
    assert (east, north, up) == pytest.approx((30.0, -40.0, 2.0), abs=0.02)  # degE7 / mm quantisation
    assert fixes[0].fix_type == 3 and fixes[0].satellites == 12
    assert fixes[0].speed_mps == pytest.approx(1.0)
    assert fixes[0].course_rad == pytest.approx(math.pi / 4, abs=1e-3)
    assert imus[0].gyro_xyz_rps == pytest.approx((0.0, 0.0, 0.2), abs=1e-3)
    assert imus[0].accel_xyz_mps2 == pytest.approx((0.1, 0.2, 9.80665), abs=0.01)
    assert link.last_heartbeat_ns == 0
    assert link.counters.bad_frames == 0
    assert sink.on(SENSORS_GPS)[0]["eph_m"] == 0.0


def test_recorded_raw_frames_parse_with_a_fresh_pymavlink_parser():
    clock, sink, link, sim = make_pair()
    run(clock, link, sim, TRUTH, 0.5)
    raw = sink.on(MAVLINK_RAW)
    assert {r["name"] for r in raw} == {"HEARTBEAT", "SYS_STATUS", "GPS_RAW_INT", "SCALED_IMU", "ATTITUDE"}
    parser = mavlink2.MAVLink(None)
    for record in raw:
        (msg,) = parser.parse_buffer(base64.b64decode(record["data"]))
        assert msg.get_type() == record["name"]
        assert msg.get_msgId() == record["msgid"]
        assert (msg.get_srcSystem(), msg.get_srcComponent()) == (record["sysid"], record["compid"])
        assert record["direction"] == "rx"
    assert len(raw) == 1 + 1 + 3 + 25 + 5  # heartbeat, SYS_STATUS 1 Hz, GPS 5, IMU 50, attitude 10 Hz, 0.5 s


def test_gps_noise_has_the_configured_size_and_is_seeded():
    def fixes(seed):
        clock, _, link, sim = make_pair(seed=seed, gps_noise_m=0.5, gps_rate_hz=50.0)
        return [r for r in run(clock, link, sim, TRUTH, 4.0) if isinstance(r, GpsFix)]

    first = fixes(7)
    assert [(f.lat_deg, f.lon_deg) for f in first] == [(f.lat_deg, f.lon_deg) for f in fixes(7)]
    assert [(f.lat_deg, f.lon_deg) for f in first] != [(f.lat_deg, f.lon_deg) for f in fixes(8)]
    east = np.array([pymap3d.geodetic2enu(f.lat_deg, f.lon_deg, f.alt_m, *DATUM)[0] for f in first])
    assert len(east) == 200
    assert east.mean() == pytest.approx(30.0, abs=0.15)
    assert east.std() == pytest.approx(0.5, rel=0.2)
    assert first[0].eph_m == pytest.approx(0.5)


def test_autopilot_hears_the_companion_heartbeat():
    _, _, link, sim = make_pair()
    link.send_heartbeat()
    link.send_heartbeat()
    assert sim.poll() == 2
    assert sim.heartbeats_received == 2
    assert sim.last_heartbeat.type == mavlink2.MAV_TYPE_ONBOARD_CONTROLLER
    assert sim.poll() == 0


def test_reversing_reports_course_opposite_to_yaw():
    clock, _, link, sim = make_pair(gps_noise_m=0.0)
    reverse = AutopilotTruth(0.0, 0.0, 0.0, 0.0, -0.5, 0.0, (0.0, 0.0, 9.80665))
    fix = next(r for r in run(clock, link, sim, reverse, 0.1) if isinstance(r, GpsFix))
    assert fix.speed_mps == pytest.approx(0.5)
    assert abs(fix.course_rad) == pytest.approx(math.pi, abs=1e-3)


@pytest.mark.parametrize(
    ("speed", "lateral", "course_deg"),
    [
        (1.0, -1.0, -45.0),  # along the contour facing east, sliding downhill (right): south-east
        (0.0, 0.5, 90.0),  # parked, sliding to its left: north
        (-1.0, 1.0, 135.0),  # backing west while sliding north: north-west
    ],
)
def test_a_sliding_body_reports_its_ground_track_not_its_heading(speed, lateral, course_deg):
    """The GPS measures where the rover goes: a sideways slide adds to its speed and turns its course off
    the heading (yaw 0, facing east)."""
    clock, _, link, sim = make_pair(gps_noise_m=0.0)
    sliding = AutopilotTruth(0.0, 0.0, 0.0, 0.0, speed, 0.0, (0.0, 0.0, 9.80665), lateral_speed_mps=lateral)
    fix = next(r for r in run(clock, link, sim, sliding, 0.1) if isinstance(r, GpsFix))
    assert fix.speed_mps == pytest.approx(math.hypot(speed, lateral), abs=0.01)
    assert math.degrees(fix.course_rad) == pytest.approx(course_deg, abs=0.01)


def test_the_imu_leaves_first_on_a_step_where_every_stream_is_due():
    # The IMU paces the rover's control loop: the other streams' encoding must not delay its send.
    _clock, sink, link, sim = make_pair()
    sim.step(TRUTH)  # at t = 0 every stream is due
    link.poll()
    names = [r["name"] for r in sink.on(MAVLINK_RAW)]
    assert set(names) == {"HEARTBEAT", "SYS_STATUS", "GPS_RAW_INT", "SCALED_IMU", "ATTITUDE"}
    assert names[0] == "SCALED_IMU"


@pytest.mark.parametrize("datum", [DATUM, (-33.9, 151.2, 12.5), (89.5, -179.0, -30.0)])
def test_gps_geodesy_in_steps_gives_pymap3d_enu2geodetic_bits(datum):
    """The GPS fix's ENU -> geodetic, done with the datum's ECEF position computed once, is exactly
    ``pymap3d.enu2geodetic`` (the fixes' bytes must not move)."""
    sim = SimAutopilot(
        memory_pipe_pair()[1],
        SimClock(),
        np.random.default_rng(0),
        datum_lat_deg=datum[0],
        datum_lon_deg=datum[1],
        datum_alt_m=datum[2],
    )
    points = np.random.default_rng(3).uniform(-2000.0, 2000.0, size=(200, 3)).tolist()
    for east, north, up in [*points, [0.0, 0.0, 0.0]]:
        ours = [float(v) for v in sim._enu_to_geodetic(east, north, up)]
        theirs = [float(v) for v in pymap3d.enu2geodetic(east, north, up, *datum)]
        assert ours == theirs


@pytest.mark.parametrize("latency_s", [0.0, 0.1])
def test_each_gps_fix_reports_the_truth_of_its_moment(latency_s):
    """Without a look-back the autopilot keeps only the truth of the ticks a fix is due; with a latency
    it keeps every tick's. Either way a fix reports where the rover was ``latency_s`` before it."""
    clock, _, link, sim = make_pair(
        gps_noise_m=0.0,
        gps=None
        if latency_s == 0.0
        else GpsModel(np.random.default_rng(1), FaultSchedule(), noise_m=0.0, latency_s=latency_s),
    )
    fixes = []
    for tick in range(300):
        t_s = tick * DT_S
        sim.step(TRUTH._replace(x_m=10.0 * t_s, y_m=-3.0 * t_s))
        fixes += [(clock.now_ns(), r) for r in link.poll() if isinstance(r, GpsFix)]
        clock.advance(to_ns(DT_S))
    assert len(fixes) == 15
    for t_ns, fix in fixes:
        east, north, _ = pymap3d.geodetic2enu(fix.lat_deg, fix.lon_deg, fix.alt_m, *DATUM)
        seen_s = max(0.0, t_ns / 1e9 - latency_s)
        assert (east, north) == pytest.approx((10.0 * seen_s, -3.0 * seen_s), abs=0.02)


def _wire_bytes(*, skip_until_due, latency_s, seconds=3.0):
    """What the autopilot sends over ``seconds`` of a moving truth, stepped every tick or only from its
    ``next_truth_ns`` on (as the world steps it)."""
    clock = SimClock()
    companion_end, autopilot_end = memory_pipe_pair()
    rng = np.random.default_rng(4)
    gps = GpsModel(rng, FaultSchedule(), noise_m=0.5, latency_s=latency_s)
    sim = SimAutopilot(
        autopilot_end, clock, rng, datum_lat_deg=DATUM[0], datum_lon_deg=DATUM[1], datum_alt_m=DATUM[2],
        gps=gps, imu_rate_hz=50.0, gps_rate_hz=5.0,
    )  # fmt: skip
    wire = b""
    steps = 0
    for tick in range(round(seconds / DT_S)):
        clock.advance(to_ns(DT_S))
        if skip_until_due and clock.now_ns() < sim.next_truth_ns:
            continue
        truth = TRUTH._replace(x_m=0.01 * tick, y_m=-0.02 * tick, yaw_rad=0.001 * tick)
        sim.step(truth)
        steps += 1
        wire += companion_end.read()
    return wire, steps


@pytest.mark.parametrize("latency_s", [0.0, 0.15])
def test_steps_left_out_before_next_truth_ns_change_nothing_sent(latency_s):
    every, every_steps = _wire_bytes(skip_until_due=False, latency_s=latency_s)
    skipping, skipping_steps = _wire_bytes(skip_until_due=True, latency_s=latency_s)
    assert skipping == every and len(every) > 0
    # Without a look-back the IMU's 20 ms leaves every other 10 ms tick out (the first tick, 10 ms after
    # the start, has everything due); with one, no tick is left out.
    assert skipping_steps == (every_steps // 2 + 1 if latency_s == 0.0 else every_steps)


def test_imu_fields_past_int16_are_clamped_each_on_its_own_side():
    _clock, sink, link, sim = make_pair(gyro_noise_rps=0.0, accel_noise_mps2=0.0)
    # 400 m/s^2 backward is ~-40 800 mG (past int16); -50 rad/s of yaw rate is +50 000 mrad/s in FRD.
    violent = TRUTH._replace(yaw_rate_rps=-50.0, accel_body_mps2=(-400.0, 0.2, 9.80665))
    sim.step(violent)
    link.poll()
    (record,) = [r for r in sink.on(MAVLINK_RAW) if r["name"] == "SCALED_IMU"]
    (msg,) = mavlink2.MAVLink(None).parse_buffer(base64.b64decode(record["data"]))
    assert (msg.xacc, msg.zgyro) == (-32767, 32767)
    # The fields within range keep their rounded values (FLU -> FRD: y and z change sign).
    assert (msg.yacc, msg.zacc) == (round(-0.2 * 1000 / 9.80665), -1000)
    assert (msg.xgyro, msg.ygyro) == (0, 0)


@pytest.mark.parametrize(("current_a", "read_a"), [(-3.0, -3.0), (-0.01, -0.02), (2.5, 2.5), (-1e9, -327.67)])
def test_a_charging_pack_reads_as_a_negative_current_never_as_not_measured(current_a, read_a):
    clock, _sink, link, sim = make_pair()
    truth = TRUTH._replace(battery_voltage_v=24.0, battery_current_a=current_a, battery_remaining_pct=90)
    readings = run(clock, link, sim, truth, 0.1)
    batteries = [r for r in readings if isinstance(r, BatteryState)]
    assert batteries and batteries[0].current_a == pytest.approx(read_a, abs=1e-9)
