"""Byte transports for MAVLink: an in-memory pipe for lockstep, loopback-guarded UDP, and (in
``firmware_bridge.mavlink_stream``) TCP and serial; ``open_transport`` picks one from a connection string.

Every transport is non-blocking: ``read()`` returns whatever has arrived (``b""`` if nothing), so a
lockstep loop never waits on a socket.
"""

from __future__ import annotations

import errno
import ipaddress
import logging
import socket
from typing import Protocol, runtime_checkable

from firmware_bridge.errors import BridgeOperationError, BridgeSetupError
from firmware_bridge.mavlink_stream import SerialTransport, TcpTransport

logger = logging.getLogger(__name__)

_MAX_DATAGRAM = 65535
DEFAULT_SERIAL_BAUD = 115200  # pymavlink's default too; telemetry radios usually want 57600


class Transport(Protocol):
    def write(self, data: bytes) -> None: ...

    def read(self) -> bytes: ...

    def close(self) -> None: ...


@runtime_checkable
class DatagramTransport(Transport, Protocol):
    """A transport that keeps message boundaries (UDP): ``read_datagrams()`` returns what arrived, one
    ``bytes`` per datagram. A MAVLink frame never spans two datagrams, so the link parses each on its own
    and garbage in one cannot swallow a frame at the start of the next."""

    def read_datagrams(self) -> list[bytes]: ...


class MemoryPipe:
    """One direction of an in-memory byte stream: what is written is read back in order, once."""

    def __init__(self) -> None:
        self.pending = bytearray()  # written, not yet taken (read only outside: PipeEnd.read looks)

    def push(self, data: bytes) -> None:
        self.pending += data

    def take(self) -> bytes:
        if not self.pending:
            return b""  # nothing new: no copy, nothing to clear
        data = bytes(self.pending)
        self.pending.clear()
        return data


class PipeEnd:
    """One end of a ``memory_pipe_pair``: writes go to the peer, reads come from it."""

    def __init__(self, incoming: MemoryPipe, outgoing: MemoryPipe) -> None:
        self._incoming = incoming
        self._outgoing = outgoing
        self._closed = False

    def write(self, data: bytes) -> None:
        if self._closed:
            raise BridgeOperationError("write on a closed memory pipe end")
        self._outgoing.push(data)

    @property
    def waiting(self) -> int:
        """Bytes written by the peer and not read yet."""
        return len(self._incoming.pending)

    def read(self) -> bytes:
        incoming = self._incoming
        if self._closed or not incoming.pending:
            # Most reads in lockstep find nothing new (the simulated autopilot reads every physics tick,
            # the companion writes a few frames a second): answered here, without a call into the pipe.
            return b""
        return incoming.take()

    def close(self) -> None:
        self._closed = True


def memory_pipe_pair() -> tuple[PipeEnd, PipeEnd]:
    """Two connected ends; deterministic, no threads, no sockets."""
    a_to_b, b_to_a = MemoryPipe(), MemoryPipe()
    return PipeEnd(b_to_a, a_to_b), PipeEnd(a_to_b, b_to_a)


def _resolve_host(host: str, allow_remote: bool, connection: str) -> str:
    """The IPv4 address to use for ``host``; refuses anything off this machine unless allowed."""
    if host == "localhost":
        return "127.0.0.1"
    try:
        address = ipaddress.IPv4Address(host)
    except ValueError:
        if not allow_remote:
            raise BridgeSetupError(
                f"{connection!r}: host {host!r} is not a loopback IPv4 address; use 127.0.0.1, or set "
                "allow_remote on the real vehicle"
            ) from None
        try:
            return socket.gethostbyname(host)
        except OSError as err:
            raise BridgeSetupError(f"{connection!r}: cannot resolve host {host!r}: {err}") from err
    if not address.is_loopback and not allow_remote:
        raise BridgeSetupError(
            f"{connection!r}: {host} is not a loopback address; MAVLink stays on 127.0.0.1 unless "
            "allow_remote is set (real vehicle only)"
        )
    return str(address)


class UdpTransport:
    """MAVLink over UDP. ``udpin`` binds and replies to the last sender; ``udpout`` sends to the address.

    ``udpout`` talks to its configured peer only: a datagram from anyone else is dropped and counted
    (``foreign_datagrams``); replying to it would hand the link to whoever sent one datagram. To a
    loopback peer the socket is bound to loopback too, so nothing off the machine can reach it.
    """

    def __init__(self, mode: str, host: str, port: int, *, allow_remote: bool = False) -> None:
        connection = f"{mode}:{host}:{port}"
        if mode not in ("udpin", "udpout"):
            raise BridgeSetupError(f"{connection!r}: UDP mode must be udpin or udpout")
        if not 0 <= port <= 65535 or (mode == "udpout" and port == 0):
            raise BridgeSetupError(f"{connection!r}: port {port} is out of range")
        address = _resolve_host(host, allow_remote, connection)
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._socket.setblocking(False)
        self._peer: tuple[str, int] | None = None
        try:
            if mode == "udpin":
                self._socket.bind((address, port))
            else:
                self._peer = (address, port)
                if ipaddress.ip_address(address).is_loopback:
                    self._socket.bind((address, 0))
        except OSError as err:
            self._socket.close()
            raise BridgeSetupError(f"MAVLink {connection}: cannot bind: {err}{_bind_hint(err)}") from err
        self._closed = False
        self._fixed_peer = mode == "udpout"
        self.dropped_writes = 0
        self.foreign_datagrams = 0

    @property
    def local_address(self) -> tuple[str, int]:
        """Where this end listens (for udpin with port 0, the port the OS picked)."""
        host, port = self._socket.getsockname()[:2]
        return str(host), int(port)

    def fileno(self) -> int:
        """The socket's descriptor, so a loop can sleep in ``select`` until a datagram arrives."""
        return self._socket.fileno()

    def write(self, data: bytes) -> None:
        if self._closed:
            raise BridgeOperationError("write on a closed UDP transport")
        if self._peer is None:
            # udpin has nobody to talk to until the first datagram arrives.
            self.dropped_writes += 1
            return
        try:
            self._socket.sendto(data, self._peer)
        except OSError as err:
            raise BridgeOperationError(f"UDP send to {self._peer[0]}:{self._peer[1]} failed: {err}") from err

    def read(self) -> bytes:
        return b"".join(self.read_datagrams())

    def read_datagrams(self) -> list[bytes]:
        """Every datagram that has arrived from our peer, one ``bytes`` each, oldest first."""
        if self._closed:
            return []
        chunks: list[bytes] = []
        while True:
            try:
                data, sender = self._socket.recvfrom(_MAX_DATAGRAM)
            except BlockingIOError:
                break
            except OSError as err:
                # e.g. ICMP port unreachable from a udpout peer that is not up yet: not fatal.
                logger.debug("UDP receive failed: %s", err)
                break
            origin = (str(sender[0]), int(sender[1]))
            if self._fixed_peer and origin != self._peer:
                self.foreign_datagrams += 1
                if self.foreign_datagrams % 100 == 1:
                    logger.warning(
                        "MAVLink UDP: dropped a datagram from %s:%d, not our peer (%d so far)",
                        *origin,
                        self.foreign_datagrams,
                    )
                continue
            chunks.append(data)
            self._peer = origin
        return chunks

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._socket.close()


def _split_host_port(connection: str, scheme: str, rest: str) -> tuple[str, int]:
    host, sep, port_text = rest.rpartition(":")
    if not sep or not host or not port_text.isdigit():
        raise BridgeSetupError(f"MAVLink connection {connection!r} must look like {scheme}:HOST:PORT")
    return host, int(port_text)


def _serial_device_and_baud(connection: str) -> tuple[str, int]:
    """``serial:DEVICE:BAUD``, ``DEVICE,BAUD`` (pymavlink's spelling) or a bare ``/dev/...`` path."""
    spec = connection.removeprefix("serial:")
    for separator in (",", ":"):
        device, sep, baud_text = spec.rpartition(separator)
        if sep and device:
            if not baud_text.isdigit():
                raise BridgeSetupError(
                    f"MAVLink connection {connection!r}: baud {baud_text!r} is not a number"
                )
            if int(baud_text) == 0:
                # termios offers B0, which is no rate: setting it drops the line (DTR), so nothing is heard.
                raise BridgeSetupError(
                    f"MAVLink connection {connection!r}: baud 0 is not a rate (B0 hangs the line up); give "
                    "the autopilot port's rate, e.g. 921600 or 57600"
                )
            return device, int(baud_text)
    if not spec:
        raise BridgeSetupError(f"MAVLink connection {connection!r} must look like serial:DEVICE:BAUD")
    return spec, DEFAULT_SERIAL_BAUD


def _check_host(host: str, allow_remote: bool, connection: str) -> None:
    """``_resolve_host``'s loopback rule without a name lookup (a config is checked before the network)."""
    if allow_remote or host == "localhost":
        return
    try:
        loopback = ipaddress.IPv4Address(host).is_loopback
    except ValueError:
        loopback = False
    if not loopback:
        raise BridgeSetupError(
            f"{connection!r}: host {host!r} is not a loopback IPv4 address; use 127.0.0.1, or set "
            "allow_remote on the real vehicle"
        )


def check_connection(connection: str, *, allow_remote: bool = False) -> None:
    """Refuse a connection string ``open_transport`` would refuse for its spelling alone, opening nothing.

    Called when the config loads, so a typo is reported with the file and key before anything starts
    (``open_transport`` still reports what only opening can find: a busy port, a missing device).
    """
    if connection == "memory":
        return
    scheme, _, rest = connection.partition(":")
    if scheme in ("udpin", "udpout", "tcp", "tcpin"):
        host, port = _split_host_port(connection, scheme, rest)
        # Port 0 means "any" only for a listener; a sender needs a real one.
        if not 0 <= port <= 65535 or (scheme in ("udpout", "tcp") and port == 0):
            raise BridgeSetupError(f"{connection!r}: port {port} is out of range")
        _check_host(host, allow_remote, connection)
        return
    if scheme == "serial" or connection.startswith("/dev/"):
        _serial_device_and_baud(connection)
        return
    raise BridgeSetupError(
        f"unknown MAVLink connection {connection!r}; expected udpin:HOST:PORT, udpout:HOST:PORT, "
        "tcp:HOST:PORT, tcpin:HOST:PORT, serial:DEVICE:BAUD or memory"
    )


def open_transport(connection: str, *, allow_remote: bool = False) -> Transport:
    """A transport from a connection string as MAVLink users know them.

    ``udpin:HOST:PORT``, ``udpout:HOST:PORT``, ``tcp:HOST:PORT`` (connect), ``tcpin:HOST:PORT`` (listen),
    ``serial:DEVICE:BAUD``, ``DEVICE,BAUD`` or ``/dev/DEVICE`` (115200 baud). Network hosts must be
    loopback unless ``allow_remote`` (the real vehicle only).
    """
    if connection == "memory":
        raise BridgeSetupError(
            "the 'memory' MAVLink connection cannot be opened by name; build it with memory_pipe_pair()"
        )
    scheme, _, rest = connection.partition(":")
    if scheme in ("udpin", "udpout"):
        host, port = _split_host_port(connection, scheme, rest)
        return UdpTransport(scheme, host, port, allow_remote=allow_remote)
    if scheme in ("tcp", "tcpin"):
        host, port = _split_host_port(connection, scheme, rest)
        if not 0 <= port <= 65535 or (scheme == "tcp" and port == 0):
            raise BridgeSetupError(f"{connection!r}: port {port} is out of range")
        return TcpTransport(scheme, _resolve_host(host, allow_remote, connection), port)
    if scheme == "serial" or connection.startswith("/dev/"):
        device, baud = _serial_device_and_baud(connection)
        return SerialTransport(device, baud)
    raise BridgeSetupError(
        f"unknown MAVLink connection {connection!r}; expected udpin:HOST:PORT, udpout:HOST:PORT, "
        "tcp:HOST:PORT, tcpin:HOST:PORT, serial:DEVICE:BAUD or memory"
    )


def _bind_hint(err: OSError) -> str:
    """What to do about a port already taken: on a rover that is most often another MAVLink program."""
    if err.errno == errno.EADDRINUSE:
        return (
            "; another program holds that port (another rover run, mavlink-router, mavproxy?): stop it, or "
            "pick another port in [mavlink] connection and send the autopilot's stream there"
        )
    return ""
