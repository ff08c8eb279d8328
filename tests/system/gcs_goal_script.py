"""A minimal ground station, as any GCS script would be written with plain pymavlink (run as a process).

Usage: python gcs_goal_script.py PORT LAT LON. Announces itself, waits for the rover's heartbeat, sends a
MAV_CMD_DO_REPOSITION goal as COMMAND_INT until acknowledged, prints what happened line by line.
"""

import os
import sys
import time

os.environ["MAVLINK20"] = "1"  # before pymavlink is imported: speak MAVLink 2

from pymavlink import mavutil


def main() -> int:
    port, lat, lon = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
    link = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190)
    print("ready", flush=True)
    deadline = time.monotonic() + 30.0
    rover = None
    while rover is None and time.monotonic() < deadline:
        link.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        msg = link.recv_match(type="HEARTBEAT", blocking=True, timeout=0.2)
        if msg is not None and msg.type == mavutil.mavlink.MAV_TYPE_ONBOARD_CONTROLLER:
            rover = (msg.get_srcSystem(), msg.get_srcComponent())
    if rover is None:
        print("no rover heartbeat", flush=True)
        return 1
    while time.monotonic() < deadline:
        link.mav.command_int_send(
            rover[0], rover[1], mavutil.mavlink.MAV_FRAME_GLOBAL_INT, mavutil.mavlink.MAV_CMD_DO_REPOSITION,
            0, 0, -1.0, 0.0, 0.0, 0.0, round(lat * 1e7), round(lon * 1e7), 0.0,
        )  # fmt: skip
        print("sent", flush=True)
        ack = link.recv_match(type="COMMAND_ACK", blocking=True, timeout=1.0)
        if ack is not None and ack.command == mavutil.mavlink.MAV_CMD_DO_REPOSITION:
            print(f"ack {ack.result}", flush=True)
            return 0
    print("no ack", flush=True)
    return 1


if __name__ == "__main__":
    sys.exit(main())
