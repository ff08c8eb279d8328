"""Byte-stream transports for MAVLink: TCP (``tcp:`` client, ``tcpin:`` listener) and serial devices.

Like the UDP and memory transports they never block after opening: ``read()`` returns what has arrived
(``b""`` if nothing), ``write()`` sends what the OS takes now and keeps the rest for the next call. A
backlog past ``MAX_BACKLOG`` bytes (the peer stopped reading) is dropped and counted in
``dropped_bytes``: telemetry that old is worthless and the loop must not grow memory without bound.

Serial uses the POSIX termios interface of the standard library (raw 8N1, no flow control), so no extra
package is needed on the companion computer (Linux); pymavlink does not depend on pyserial either.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import socket
import termios
import tty

from firmware_bridge.errors import BridgeOperationError, BridgeSetupError

logger = logging.getLogger(__name__)

MAX_BACKLOG = 64 * 1024
_READ_SIZE = 65536
_RETRY_LATER = (errno.EAGAIN, errno.EWOULDBLOCK, errno.EINTR)


class _Backlog:
    """Bytes accepted by ``write()`` that the OS has not taken yet."""

    def __init__(self) -> None:
        self.pending = bytearray()
        self.dropped_bytes = 0

    def add(self, data: bytes) -> None:
        if len(self.pending) + len(data) > MAX_BACKLOG:
            self.dropped_bytes += len(self.pending)
            logger.warning("MAVLink stream peer is not reading: dropped %d queued bytes", len(self.pending))
            self.pending.clear()
        self.pending += data


class TcpTransport:
    """``tcp:HOST:PORT`` connects to a listener; ``tcpin:HOST:PORT`` listens and takes one peer at a time.

    When the peer goes away, ``connected`` turns False, reads return ``b""`` and writes raise
    ``BridgeOperationError`` (the link counts them); a ``tcpin`` listener then accepts the next peer.
    """

    def __init__(
        self,
        mode: str,
        address: str,
        port: int,
        *,
        connect_timeout_s: float = 5.0,
    ) -> None:
        self._name = f"{mode}:{address}:{port}"
        self._backlog = _Backlog()
        self._listener: socket.socket | None = None
        self._socket: socket.socket | None = None
        self._closed = False
        if mode == "tcpin":
            self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            try:
                self._listener.bind((address, port))
                self._listener.listen(1)
            except OSError as err:
                self._listener.close()
                raise BridgeSetupError(f"{self._name!r}: cannot listen: {err}") from err
            self._listener.setblocking(False)
        elif mode == "tcp":
            try:
                # Opening may block (up to connect_timeout_s): it happens once, before the loop starts.
                sock = socket.create_connection((address, port), timeout=connect_timeout_s)
            except OSError as err:
                raise BridgeSetupError(
                    f"{self._name!r}: cannot connect: {err}; is the autopilot (or SITL) listening there?"
                ) from err
            self._adopt(sock)
        else:
            raise BridgeSetupError(f"{self._name!r}: TCP mode must be tcp or tcpin")

    def _adopt(self, sock: socket.socket) -> None:
        sock.setblocking(False)
        # MAVLink frames are small and latency matters more than packing them.
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._socket = sock
        logger.info("MAVLink %s connected to %s", self._name, sock.getpeername())

    @property
    def connected(self) -> bool:
        return self._socket is not None

    @property
    def dropped_bytes(self) -> int:
        return self._backlog.dropped_bytes

    @property
    def local_address(self) -> tuple[str, int]:
        """The listener's address (for ``tcpin`` on port 0, the port the OS picked) or our socket's."""
        sock = self._listener if self._listener is not None else self._socket
        if sock is None:
            raise BridgeOperationError(f"{self._name!r} is closed")
        host, port = sock.getsockname()[:2]
        return str(host), int(port)

    def _accept(self) -> None:
        if self._listener is None or self._socket is not None:
            return
        try:
            sock, _ = self._listener.accept()
        except (BlockingIOError, InterruptedError):
            return
        self._adopt(sock)

    def _lost(self, why: str) -> None:
        logger.warning("MAVLink %s: peer gone (%s)", self._name, why)
        if self._socket is not None:
            self._socket.close()
        self._socket = None
        self._backlog.pending.clear()

    def write(self, data: bytes) -> None:
        if self._closed:
            raise BridgeOperationError(f"write on a closed {self._name!r}")
        self._accept()
        if self._socket is None:
            raise BridgeOperationError(f"{self._name!r}: not connected")
        self._backlog.add(data)
        self._flush()

    def _flush(self) -> None:
        while self._backlog.pending and self._socket is not None:
            try:
                sent = self._socket.send(self._backlog.pending)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as err:
                self._lost(str(err))
                raise BridgeOperationError(f"{self._name!r}: send failed: {err}") from err
            del self._backlog.pending[:sent]

    def read(self) -> bytes:
        if self._closed:
            return b""
        self._accept()
        chunks: list[bytes] = []
        while self._socket is not None:
            try:
                data = self._socket.recv(_READ_SIZE)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as err:
                self._lost(str(err))
                break
            if not data:
                self._lost("closed by the peer")
                break
            chunks.append(data)
        if self._socket is not None and self._backlog.pending:
            # A failure is already logged by _lost; reads still return what arrived.
            with contextlib.suppress(BridgeOperationError):
                self._flush()
        return b"".join(chunks)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for sock in (self._socket, self._listener):
            if sock is not None:
                sock.close()
        self._socket = None


def _baud_constant(baud: int, name: str) -> int:
    constant = getattr(termios, f"B{baud}", None)
    if not isinstance(constant, int):
        raise BridgeSetupError(f"{name!r}: {baud} baud is not a rate this system's serial driver offers")
    return constant


def _serial_open_hint(err: OSError) -> str:
    """What to check for a serial device that did not open, from what the OS said."""
    if err.errno == errno.ENOENT:
        return "is the autopilot plugged in, and is this its name (ls /dev/serial/by-id/ /dev/tty*)?"
    if err.errno in (errno.EACCES, errno.EPERM):
        return "the user running rover may not open it: add that user to the device's group (dialout)"
    if err.errno == errno.EBUSY:
        return "another program holds it (mavproxy, mavlink-router, ModemManager?)"
    return "is it plugged in, and may the user running rover open it (dialout)?"


class SerialTransport:
    """A serial device (``/dev/ttyUSB0``, ``/dev/ttyACM0``, ``/dev/serial0``...) in raw mode at ``baud``."""

    def __init__(self, device: str, baud: int) -> None:
        self._name = f"{device},{baud}"
        speed = _baud_constant(baud, self._name)
        self._backlog = _Backlog()
        self._closed = False
        try:
            self._fd = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError as err:
            raise BridgeSetupError(
                f"MAVLink serial device {device} ({baud} baud): cannot open: {err.strerror or err}; "
                f"{_serial_open_hint(err)}"
            ) from err
        try:
            tty.setraw(self._fd)
            attributes = termios.tcgetattr(self._fd)
            attributes[2] = (attributes[2] & ~termios.CRTSCTS) | termios.CLOCAL | termios.CREAD
            attributes[4] = attributes[5] = speed  # ispeed, ospeed
            termios.tcsetattr(self._fd, termios.TCSANOW, attributes)
        except (termios.error, OSError) as err:
            os.close(self._fd)
            raise BridgeSetupError(
                f"{self._name!r}: not a serial device, or cannot set it up: {err}"
            ) from err
        logger.info("MAVLink serial %s open", self._name)

    @property
    def dropped_bytes(self) -> int:
        return self._backlog.dropped_bytes

    def write(self, data: bytes) -> None:
        if self._closed:
            raise BridgeOperationError(f"write on a closed serial port {self._name!r}")
        self._backlog.add(data)
        self._flush()

    def _flush(self) -> None:
        pending = self._backlog.pending
        while pending:
            try:
                written = os.write(self._fd, pending)
            except OSError as err:
                if err.errno in _RETRY_LATER:
                    return
                raise BridgeOperationError(f"serial write to {self._name!r} failed: {err}") from err
            del pending[:written]

    def read(self) -> bytes:
        if self._closed:
            return b""
        chunks: list[bytes] = []
        while True:
            try:
                data = os.read(self._fd, _READ_SIZE)
            except OSError as err:
                if err.errno not in _RETRY_LATER:
                    # e.g. EIO when a USB adapter is unplugged: keep the loop alive, the link timeout tells.
                    logger.debug("serial read from %s failed: %s", self._name, err)
                break
            if not data:
                break
            chunks.append(data)
        if self._backlog.pending:
            try:
                self._flush()
            except BridgeOperationError as err:
                logger.debug("%s", err)
        return b"".join(chunks)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            os.close(self._fd)
