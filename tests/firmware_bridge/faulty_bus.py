"""A test double around a python-can bus that can go bus-off the way a real SocketCAN controller does."""

from __future__ import annotations

from collections import deque

import can

from firmware_bridge.can_health import CAN_ERR_BUSOFF, CAN_ERR_CRTL, CAN_ERR_RESTARTED


def error_frame(error_class: int, status: int = 0) -> can.Message:
    """An error frame laid out as Linux delivers it: class in the id, controller status in data[1]."""
    data = bytes([0, status, 0, 0, 0, 0, 0, 0])
    return can.Message(arbitration_id=error_class, is_error_frame=True, is_extended_id=False, data=data)


class FaultyBus:
    """While off, sends fail and nothing is received; the error frames are delivered on recv."""

    def __init__(self, bus: can.BusABC) -> None:
        self._bus = bus
        self.off = False
        self.state = can.BusState.ACTIVE
        self._injected: deque[can.Message] = deque()

    def go_bus_off(self) -> None:
        self.off = True
        self._injected.append(error_frame(CAN_ERR_BUSOFF))

    def restart(self) -> None:
        self.off = False
        self._injected.append(error_frame(CAN_ERR_RESTARTED))

    def inject(self, msg: can.Message) -> None:
        self._injected.append(msg)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self.off:
            raise can.CanOperationError("Transmit buffer full / network down (bus-off)")
        self._bus.send(msg, timeout)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        if self._injected:
            return self._injected.popleft()
        if self.off:
            # A bus-off controller hears nothing; what the peers sent meanwhile is lost.
            while self._bus.recv(timeout=0) is not None:
                pass
            return None
        return self._bus.recv(timeout)

    def shutdown(self) -> None:
        self._bus.shutdown()


__all__ = ["CAN_ERR_CRTL", "FaultyBus", "error_frame"]
