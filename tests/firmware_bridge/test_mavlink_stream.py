import os
import socket
import time

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.errors import BridgeOperationError
from firmware_bridge.mavlink_link import GpsFix, MavlinkLink
from firmware_bridge.mavlink_stream import MAX_BACKLOG, SerialTransport, TcpTransport
from firmware_bridge.mavlink_transport import open_transport
from logs.clock import SimClock
from logs.sink import MemorySink

DEADLINE_S = 5.0


def gps_frame() -> bytes:
    mav = mavlink2.MAVLink(None, 1, 1)
    msg = mavlink2.MAVLink_gps_raw_int_message(1, 3, 473977420, 85455940, 488000, 150, 300, 250, 9000, 12)
    return bytes(msg.pack(mav))


def until(produce, what):
    """Call ``produce`` until it returns something truthy; fail naming ``what`` after the deadline."""
    deadline = time.monotonic() + DEADLINE_S
    while time.monotonic() < deadline:
        if result := produce():
            return result
        time.sleep(0.001)
    pytest.fail(f"timed out waiting for {what}")


def recv_some(sock: socket.socket) -> bytes:
    sock.settimeout(DEADLINE_S)
    return sock.recv(65536)


@pytest.fixture
def listener():
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.bind(("127.0.0.1", 0))
    sock.listen(1)
    sock.settimeout(DEADLINE_S)
    yield sock
    sock.close()


def test_tcp_client_carries_mavlink_both_ways_and_notices_the_peer_leaving(listener):
    port = listener.getsockname()[1]
    transport = open_transport(f"tcp:127.0.0.1:{port}")
    assert isinstance(transport, TcpTransport) and transport.connected
    autopilot, _ = listener.accept()
    with autopilot, MavlinkLink(transport, SimClock(3), MemorySink()) as link:
        autopilot.sendall(gps_frame())
        (fix,) = until(link.poll, "the GPS fix over TCP")
        assert isinstance(fix, GpsFix) and fix.lat_deg == pytest.approx(47.397742)
        link.send_heartbeat()
        (heartbeat,) = mavlink2.MAVLink(None).parse_buffer(recv_some(autopilot))
        assert heartbeat.get_type() == "HEARTBEAT" and heartbeat.get_srcComponent() == 191
        autopilot.close()
        until(lambda: link.poll() == [] and not transport.connected, "the closed connection to be noticed")
        link.send_heartbeat()  # counted, not raised: the loop keeps running
        assert link.counters.tx_errors == 1


def test_tcpin_listens_on_an_os_chosen_port_and_takes_the_next_peer(request):
    transport = open_transport("tcpin:127.0.0.1:0")
    assert isinstance(transport, TcpTransport)
    host, port = transport.local_address
    assert host == "127.0.0.1" and port > 0
    try:
        with pytest.raises(BridgeOperationError, match="not connected"):
            transport.write(b"nobody yet")
        for round_number in range(2):
            with socket.create_connection((host, port), timeout=DEADLINE_S) as peer:
                peer.sendall(b"ping %d" % round_number)
                assert until(transport.read, "data from the peer") == b"ping %d" % round_number
                transport.write(b"pong")
                assert recv_some(peer) == b"pong"
            until(lambda: transport.read() == b"" and not transport.connected, "the peer to leave")
    finally:
        transport.close()
        transport.close()


def test_tcp_backlog_is_bounded_when_the_peer_stops_reading(listener):
    port = listener.getsockname()[1]
    transport = open_transport(f"tcp:127.0.0.1:{port}")
    assert isinstance(transport, TcpTransport)
    peer, _ = listener.accept()
    with peer:
        peer.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        written = 0
        while transport.dropped_bytes == 0 and written < 200_000_000:  # far more than socket buffers hold
            transport.write(bytes(8192))
            written += 8192
        # the queue is dropped once it would pass MAX_BACKLOG: never more than that at a time
        assert 0 < transport.dropped_bytes <= MAX_BACKLOG
        assert transport.connected
    transport.close()


def test_tcp_connect_refused_is_a_setup_error(listener):
    port = listener.getsockname()[1]
    listener.close()
    with pytest.raises(Exception, match="cannot connect") as caught:
        open_transport(f"tcp:localhost:{port}")
    assert type(caught.value).__name__ == "BridgeSetupError"


@pytest.mark.parametrize("spelling", ["serial:{path}:57600", "{path},57600", "{path}"])
def test_serial_over_a_pseudo_terminal(spelling):
    controller, device = os.openpty()
    path = os.ttyname(device)
    try:
        transport = open_transport(spelling.format(path=path))
        assert isinstance(transport, SerialTransport)
        with MavlinkLink(transport, SimClock(9), MemorySink()) as link:
            os.write(controller, gps_frame())
            (fix,) = until(link.poll, "the GPS fix over the serial line")
            assert isinstance(fix, GpsFix) and fix.t_ns == 9
            link.send_heartbeat()
            (heartbeat,) = mavlink2.MAVLink(None).parse_buffer(
                until(lambda: os.read(controller, 4096), "a frame")
            )
            assert heartbeat.get_type() == "HEARTBEAT"
        with pytest.raises(BridgeOperationError, match="closed serial port"):
            transport.write(b"x")
    finally:
        os.close(controller)
        os.close(device)
