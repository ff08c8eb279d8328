"""Real time: a pymavlink ground station on UDP 127.0.0.1 uploads a mission to ``rover run``'s MAVLink link,
downloads it back, leaves an upload unfinished, which the rover abandons on its monotonic clock, and starts
the mission with MAV_CMD_MISSION_START."""

from __future__ import annotations

import signal
import socket
import time
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from logs.reader import read_messages
from tests.firmware_bridge.ground_station import MISSION, ROVER, mission_start, waypoint
from tests.runtime.run_config import rover_run_config
from tests.runtime.test_rover_run import start_rover, wait_until_running

pytestmark = pytest.mark.realtime  # the rover abandons an unfinished upload on its monotonic clock

DATUM = (47.0, 8.0)
# Latitude, longitude near the datum: inside the config's 10 m map.
PLAN = [(47.00002, 8.00003), (47.00005, 8.00006), (47.00003, 8.0001)]
WAIT_S = 5.0


class UdpGroundStation:
    """A ground station's UDP socket on loopback (its port from the OS), speaking as 255/190."""

    def __init__(self, rover_port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.rover = ("127.0.0.1", rover_port)
        self.mav = mavlink2.MAVLink(None, 255, 190)
        self.parser = mavlink2.MAVLink(None)
        self.parser.robust_parsing = True

    def send(self, msg: Any) -> None:
        self.sock.sendto(bytes(msg.pack(self.mav)), self.rover)

    def wait_for(self, name: str, timeout_s: float = WAIT_S) -> Any:
        """The next message named ``name`` (others are passed over), or AssertionError at the timeout."""
        deadline = time.monotonic() + timeout_s
        while (left := deadline - time.monotonic()) > 0:
            self.sock.settimeout(left)
            try:
                data = self.sock.recv(65535)
            except TimeoutError:
                break
            for msg in self.parser.parse_buffer(data) or []:
                if msg.get_type() == name:
                    return msg
        raise AssertionError(f"no {name} from the rover within {timeout_s} s")

    def close(self) -> None:
        self.sock.close()


def test_rover_run_takes_a_mission_upload_and_abandons_a_partial_one_in_real_time(tmp_path: Path) -> None:
    config = tmp_path / "rover.toml"
    config.write_text(
        rover_run_config("missiontest", f"mission-{time.monotonic_ns()}")
        + f"[estimator]\ndatum_lat_deg = {DATUM[0]}\ndatum_lon_deg = {DATUM[1]}\n"
    )
    out = tmp_path / "run"
    process = start_rover(config, out, "--no-telemetry")
    station: UdpGroundStation | None = None
    try:
        announced = wait_until_running(process)
        port = int(announced[0].split("(listening on 127.0.0.1:")[1].split(")")[0])
        station = UdpGroundStation(port)
        station.send(mavlink2.MAVLink_heartbeat_message(mavlink2.MAV_TYPE_GCS, 8, 0, 0, 0, 3))
        station.wait_for("HEARTBEAT")  # the rover answers the last sender

        items = [waypoint(seq, lat, lon) for seq, (lat, lon) in enumerate(PLAN)]
        station.send(mavlink2.MAVLink_mission_count_message(*ROVER, len(items), MISSION))
        for seq in range(len(items)):
            request = station.wait_for("MISSION_REQUEST_INT")
            assert request.seq == seq
            station.send(items[seq])
        assert station.wait_for("MISSION_ACK").type == mavlink2.MAV_MISSION_ACCEPTED
        current = station.wait_for("MISSION_CURRENT")  # a parked rover: uploaded, not driven
        assert (current.total, current.mission_state) == (3, mavlink2.MISSION_STATE_NOT_STARTED)

        # An upload left unfinished: asked again every 250 ms, 5 times, then cancelled.
        station.send(mavlink2.MAVLink_mission_count_message(*ROVER, 2, MISSION))
        first = time.monotonic()
        for _ in range(6):
            assert station.wait_for("MISSION_REQUEST_INT").seq == 0
        cancelled = station.wait_for("MISSION_ACK")
        assert cancelled.type == mavlink2.MAV_MISSION_OPERATION_CANCELLED
        assert time.monotonic() - first >= 1.2  # five 250 ms timeouts on the rover's own clock

        # The mission in force is the first upload, field for field.
        station.send(mavlink2.MAVLink_mission_request_list_message(*ROVER, MISSION))
        assert station.wait_for("MISSION_COUNT").count == 3
        for seq, sent in enumerate(items):
            station.send(mavlink2.MAVLink_mission_request_int_message(*ROVER, seq, MISSION))
            item = station.wait_for("MISSION_ITEM_INT")
            assert (item.seq, item.x, item.y, item.frame) == (seq, sent.x, sent.y, sent.frame)
        station.send(mavlink2.MAVLink_mission_ack_message(*ROVER, mavlink2.MAV_MISSION_ACCEPTED, MISSION))

        station.send(mission_start(0, 0))
        started = station.wait_for("COMMAND_ACK")
        assert (started.command, started.result) == (
            mavlink2.MAV_CMD_MISSION_START,
            mavlink2.MAV_RESULT_ACCEPTED,
        )
        current = station.wait_for("MISSION_CURRENT")
        assert (current.seq, current.mission_state) == (0, mavlink2.MISSION_STATE_ACTIVE)
        time.sleep(1.5)  # a mavlink/stats window closes with the download in it
        process.send_signal(signal.SIGINT)
        process.communicate(timeout=20)
    finally:
        if station is not None:
            station.close()
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 0

    mcap = out / "rover.mcap"
    events = [m.message for m in read_messages(mcap, ["safety/events"]) if m.message["kind"] == "mission"]
    assert [e["detail"].split(":")[0] for e in events] == [
        "mission of 3 waypoints from MAVLink upload by 255/190 on the autopilot link"
    ]
    stats = [m.message for m in read_messages(mcap, ["mavlink/stats"])]
    totals = {
        name: sum(s.get(name, 0) for s in stats)
        for name in ("missions_accepted", "mission_timeouts", "mission_downloads", "mission_resends")
    }
    assert totals == {
        "missions_accepted": 1,
        "mission_timeouts": 1,
        "mission_downloads": 1,
        "mission_resends": 5,
    }
    logged = [m.message["message"] for m in read_messages(mcap, ["log"])]
    assert any("abandoned: item 0 of 2 not received after 6 requests" in line for line in logged), logged
