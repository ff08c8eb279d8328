import json
import math
import subprocess
import sys
import textwrap
import time

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_commands import GoalRequest
from firmware_bridge.mavlink_link import BatteryState, ImuSample, MavlinkLink
from firmware_bridge.mavlink_transport import memory_pipe_pair, open_transport
from logs.clock import MonotonicClock, SimClock, to_ns
from logs.sink import MemorySink
from logs.topics import SAFETY_EVENTS

KEY = bytes(range(32))


def gcs(key=None, sysid=255, compid=190):
    mav = mavlink2.MAVLink(None, sysid, compid)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.link_id = 1
        mav.signing.timestamp = 1000
    return mav


def reposition(lat=47.3977420, lon=8.5455940, frame=mavlink2.MAV_FRAME_GLOBAL_INT, target=(1, 191)):
    return mavlink2.MAVLink_command_int_message(
        *target,
        frame,
        mavlink2.MAV_CMD_DO_REPOSITION,
        0,
        0,
        -1,
        0,
        0,
        math.nan,
        round(lat * 1e7),
        round(lon * 1e7),
        0,
    )


def replies(wire):
    return mavlink2.MAVLink(None).parse_buffer(wire) or []


def rig(**kwargs):
    companion, ground = memory_pipe_pair()
    sink = MemorySink()
    link = MavlinkLink(companion, SimClock(5), sink, system_id=1, component_id=191, **kwargs)
    return link, ground, sink


def test_reposition_command_becomes_a_goal_and_is_acked():
    link, ground, _ = rig()
    ground.write(bytes(reposition().pack(gcs())))
    (goal,) = link.poll()
    assert goal == GoalRequest(
        5, pytest.approx(47.397742), pytest.approx(8.545594), "MAV_CMD_DO_REPOSITION", 255, 190
    )
    (ack,) = replies(ground.read())
    assert ack.get_type() == "COMMAND_ACK"
    assert ack.command == mavlink2.MAV_CMD_DO_REPOSITION and ack.result == mavlink2.MAV_RESULT_ACCEPTED
    assert (ack.target_system, ack.target_component) == (255, 190)
    assert link.counters.goals_accepted == 1


def test_position_target_becomes_a_goal_and_is_echoed():
    link, ground, _ = rig()
    msg = mavlink2.MAVLink_set_position_target_global_int_message(
        0,
        1,
        0,
        mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        0b110111111000,
        473977420,
        85455940,
        0,
        *[0.0] * 8,
    )
    ground.write(bytes(msg.pack(gcs())))
    (goal,) = link.poll()
    assert goal.source == "SET_POSITION_TARGET_GLOBAL_INT" and goal.lat_deg == pytest.approx(47.397742)
    (echo,) = replies(ground.read())
    assert echo.get_type() == "POSITION_TARGET_GLOBAL_INT"
    assert (echo.lat_int, echo.lon_int) == (473977420, 85455940)


@pytest.mark.parametrize(
    ("msg", "result", "reason"),
    [
        (reposition(frame=mavlink2.MAV_FRAME_LOCAL_NED), mavlink2.MAV_RESULT_DENIED, "not global"),
        (reposition(lat=91.0), mavlink2.MAV_RESULT_DENIED, "out of range"),
        (
            mavlink2.MAVLink_command_long_message(1, 191, mavlink2.MAV_CMD_NAV_LAND, 0, *[0.0] * 7),
            mavlink2.MAV_RESULT_UNSUPPORTED,
            "not supported",
        ),
    ],
)
def test_bad_goals_are_refused_with_the_reason(msg, result, reason):
    link, ground, _ = rig()
    ground.write(bytes(msg.pack(gcs())))
    assert link.poll() == []
    ack, text = replies(ground.read())
    assert ack.get_type() == "COMMAND_ACK" and ack.result == result
    assert text.get_type() == "STATUSTEXT" and reason in text.text
    assert link.counters.commands_rejected == 1


def test_commands_for_someone_else_are_left_alone():
    link, ground, _ = rig()
    ground.write(bytes(reposition(target=(1, 1)).pack(gcs())) + bytes(reposition(target=(2, 0)).pack(gcs())))
    assert link.poll() == []
    assert ground.read() == b""


def test_long_status_text_is_chunked():
    link, ground, _ = rig()
    link.send_status_text("x" * 120, mavlink2.MAV_SEVERITY_NOTICE)
    chunks = replies(ground.read())
    assert [len(c.text) for c in chunks] == [50, 50, 20]
    assert {c.id for c in chunks} == {1} and [c.chunk_seq for c in chunks] == [0, 1, 2]


def test_battery_and_highres_imu_readings():
    link, ground, _ = rig()
    ap = mavlink2.MAVLink(None, 1, 1)
    frames = [
        mavlink2.MAVLink_sys_status_message(0, 0, 0, 0, 25200, 1250, 80, 0, 0, 0, 0, 0, 0),
        mavlink2.MAVLink_battery_status_message(0, 0, 0, 0, [4200] * 6 + [65535] * 4, -1, 0, 0, 77),
        mavlink2.MAVLink_highres_imu_message(0, 0.1, 0.2, -9.8, 0.01, 0.02, 0.03, 0, 0, 0, 0, 0, 0, 0, 0),
    ]
    ground.write(b"".join(bytes(f.pack(ap)) for f in frames))
    sys_status, battery, imu = link.poll()
    assert sys_status == BatteryState(5, pytest.approx(25.2), pytest.approx(12.5), 80, "SYS_STATUS")
    assert battery.voltage_v == pytest.approx(25.2) and math.isnan(battery.current_a)
    assert isinstance(imu, ImuSample)
    assert imu.accel_xyz_mps2 == pytest.approx((0.1, -0.2, 9.8))
    assert imu.gyro_xyz_rps == pytest.approx((0.01, -0.02, -0.03))


def test_link_loss_is_detected_and_reported_once():
    companion, ground = memory_pipe_pair()
    clock, sink = SimClock(), MemorySink()
    link = MavlinkLink(companion, clock, sink, link_timeout_s=3.0)
    ap = mavlink2.MAVLink(None, 1, 1)
    heartbeat = mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_GROUND_ROVER, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4, 3
    )
    for _ in range(4):
        clock.advance(to_ns(1.0))
        link.poll()
    assert not link.autopilot_link_ok
    link.poll()
    ground.write(bytes(heartbeat.pack(ap)))
    link.poll()
    assert link.autopilot_link_ok
    events = sink.on(SAFETY_EVENTS)
    assert [e["kind"] for e in events] == ["mavlink_link_lost", "mavlink_link_restored"]
    assert "no autopilot HEARTBEAT for 4.0 s" in events[0]["detail"]


def test_signed_commands_only_when_signing_is_on():
    link, ground, _ = rig(signing_key=KEY)
    signer = gcs(KEY)
    ground.write(bytes(reposition().pack(signer)))
    assert len(link.poll()) == 1
    replay = bytes(reposition(lat=10.0).pack(signer))
    ground.write(replay)
    assert len(link.poll()) == 1
    ground.write(replay)  # the same signed frame again: its timestamp is not newer
    ground.write(bytes(reposition().pack(gcs())))  # unsigned
    ground.write(bytes(reposition().pack(gcs(bytes(32)))))  # signed with another key
    telemetry = mavlink2.MAVLink_sys_status_message(0, 0, 0, 0, 25200, -1, -1, 0, 0, 0, 0, 0, 0)
    ground.write(bytes(telemetry.pack(mavlink2.MAVLink(None, 1, 1))))  # unsigned telemetry still welcome
    readings = link.poll()
    assert [type(r) for r in readings] == [BatteryState]
    assert link.counters.signature_rejected == 3
    assert link.counters.goals_accepted == 2
    # our own frames are signed
    acks = ground.read()
    assert acks[2] & mavlink2.MAVLINK_IFLAG_SIGNED


GROUND_STATION = textwrap.dedent(
    """
    import json, sys, time
    from pymavlink import mavutil

    port = int(sys.argv[1])
    gcs = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190)
    deadline = time.monotonic() + 20
    ack = None
    while ack is None and time.monotonic() < deadline:
        gcs.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        gcs.mav.command_int_send(
            1, 191, mavutil.mavlink.MAV_FRAME_GLOBAL_INT, mavutil.mavlink.MAV_CMD_DO_REPOSITION,
            0, 0, -1, 0, 0, float("nan"), 473977420, 85455940, 0,
        )
        ack = gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.5)
    if ack is None:
        sys.exit("no COMMAND_ACK")
    print(json.dumps({"command": ack.command, "result": ack.result}))
    """
)


def test_a_ground_station_in_another_process_sends_a_goal_over_udp_and_gets_an_ack():
    transport = open_transport("udpin:127.0.0.1:0")
    link = MavlinkLink(transport, MonotonicClock(), MemorySink(), system_id=1, component_id=191)
    _, port = transport.local_address
    station = subprocess.Popen(
        [sys.executable, "-c", GROUND_STATION, str(port)], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    goals = []
    try:
        deadline = time.monotonic() + 30
        while station.poll() is None and time.monotonic() < deadline:
            goals += [r for r in link.poll() if isinstance(r, GoalRequest)]
            time.sleep(0.002)
        out, err = station.communicate(timeout=10)
    finally:
        if station.poll() is None:
            station.kill()
            station.wait()
        link.close()
    assert station.returncode == 0, err.decode()
    answer = json.loads(out)
    assert answer == {"command": mavlink2.MAV_CMD_DO_REPOSITION, "result": mavlink2.MAV_RESULT_ACCEPTED}
    assert (
        goals and goals[0].lat_deg == pytest.approx(47.397742) and goals[0].lon_deg == pytest.approx(8.545594)
    )
    assert (goals[0].sysid, goals[0].compid) == (255, 190)
