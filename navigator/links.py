"""Opening the rover's links from its config: the CAN bus to the motor controllers, MAVLink to the autopilot.

On the rover that is ``socketcan``/``can0`` and a UDP (or, later, serial) MAVLink endpoint; in real-time
HIL the same config names a ``udp_multicast`` channel (inside a private network namespace) and a
loopback UDP port. Failures raise ``firmware_bridge.errors.BridgeSetupError`` naming what to check.
"""

from __future__ import annotations

from dataclasses import dataclass

from firmware_bridge.can_link import CanLink, open_bus
from firmware_bridge.errors import BridgeOperationError, BridgeSetupError
from firmware_bridge.mavlink_link import MavlinkLink, signing_key_bytes
from firmware_bridge.mavlink_stream import TcpTransport
from firmware_bridge.mavlink_transport import Transport, UdpTransport, open_transport
from firmware_bridge.vesc import VescCodec
from logs.clock import Clock
from logs.sink import MessageSink
from navigator.config import RoverConfig


@dataclass(frozen=True)
class RoverLinks:
    """The opened links, and what the real-time loop may sleep on until the pacing sensor's data lands
    (``navigator.input_wait``): the MAVLink transport for IMU or GPS pacing, the CAN bus for wheels."""

    can: CanLink
    mavlink: MavlinkLink
    pacing_sources: tuple[object, ...]
    mavlink_endpoint: str = ""  # the connection as configured, and where it listens if the OS picked

    def close(self) -> None:
        """Close both links (CAN first: it commands zero to every wheel on the way); safe to call twice."""
        try:
            self.can.close()
        finally:
            self.mavlink.close()


def open_links(config: RoverConfig, clock: Clock, sink: MessageSink) -> RoverLinks:
    """Open CAN first, then MAVLink; if MAVLink fails the CAN bus is shut again."""
    codec = VescCodec.for_profile(config.vesc)
    bus = open_bus(config.can)
    can_link = CanLink(bus, codec, clock, sink)
    try:
        transport = open_transport(config.mavlink.connection, allow_remote=config.mavlink.allow_remote)
    except BridgeSetupError:
        can_link.close()
        raise
    settings = config.mavlink
    mavlink = MavlinkLink(
        transport,
        clock,
        sink,
        system_id=settings.system_id,
        component_id=settings.component_id,
        autopilot_system_id=settings.autopilot_system_id,
        link_timeout_s=settings.link_timeout_s,
        signing_key=signing_key_bytes(settings.signing_key) if settings.signing_key else None,
        rx_budget_bytes_per_s=settings.rx_budget_bytes_per_s,
    )
    pacing: dict[str, tuple[object, ...]] = {"imu": (transport,), "gps": (transport,), "wheels": (bus,)}
    return RoverLinks(
        can_link, mavlink, pacing.get(config.pacing_sensor, ()), _endpoint(settings.connection, transport)
    )


def _endpoint(connection: str, transport: Transport) -> str:
    """``connection`` and, for a listening end (udpin, tcpin), the address it is bound to: with port 0
    in the config only the socket knows which port an autopilot or HIL peer must send to."""
    if not connection.startswith(("udpin:", "tcpin:")) or not isinstance(
        transport, (UdpTransport, TcpTransport)
    ):
        return connection
    try:
        host, port = transport.local_address
    except (OSError, BridgeOperationError):
        return connection
    return f"{connection} (listening on {host}:{port})"
