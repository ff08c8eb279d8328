"""A udpout MAVLink link talks to its configured peer only, on loopback."""

import socket
import time

from firmware_bridge.mavlink_transport import UdpTransport


def _listener() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(2.0)
    return sock


def test_a_stranger_s_datagram_is_dropped_and_does_not_redirect_the_link() -> None:
    autopilot, stranger = _listener(), _listener()
    link = UdpTransport("udpout", "127.0.0.1", autopilot.getsockname()[1])
    try:
        assert link.local_address[0] == "127.0.0.1"  # not reachable from off the machine
        link.write(b"hello")
        data, ours = autopilot.recvfrom(100)
        assert data == b"hello"
        stranger.sendto(b"junk", ours)
        autopilot.sendto(b"from the autopilot", ours)
        received = b""
        for _ in range(200):  # both datagrams are on loopback within a moment
            received += link.read()
            if received:
                break
            time.sleep(0.01)
        assert received == b"from the autopilot" and link.foreign_datagrams == 1
        link.write(b"hello2")
        assert autopilot.recvfrom(100)[0] == b"hello2"
    finally:
        link.close()
        autopilot.close()
        stranger.close()
