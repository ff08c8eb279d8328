"""The rover's own CAN controller going bus-off, for the lockstep trial's ``can`` ``off`` fault.

A bus-off is the rover's controller's state, not only the wire's: with no ACK (a cut or shorted bus) its
transmit error counter passes 255 and it leaves the bus. Its host then cannot send (socketcan refuses with
ENOBUFS / ENETDOWN, which python-can raises as ``CanOperationError``) and hears nothing, and Linux delivers
a ``CAN_ERR_BUSOFF`` error frame (python-can's socketcan bus asks for error frames by default); when the
controller restarts (``ip link ... restart-ms``), a ``CAN_ERR_RESTARTED`` one. The simulator's end of the
bus (``hil.fault_links.FaultyCanBus``) drops the frames on the wire; this wraps the other end, the rover's,
so the rover's link meets what it would meet on the vehicle and its ``can_bus_off`` failsafe can fire.

Only where one process holds both ends (lockstep, ``hil.world.SimWorld.rover_can_end``): in the real-time
peer the rover's bus is another process's, and a bus-off there is silence alone (docs/hil.md).

Simplified: a real controller's transmit queue takes a few frames before it refuses (socketcan's
``txqueuelen``, 10 by default) and sends them after the restart; here every send during the fault fails.
"""

from __future__ import annotations

from collections import deque

import can

from firmware_bridge.can_health import CAN_ERR_BUSOFF, CAN_ERR_RESTARTED
from hil.faults import FaultSchedule
from logs.clock import NS_PER_S, Clock

_ERROR_FRAME_DLC = 8  # Linux's CAN_ERR_DLC


def error_frame(error_class: int, t_ns: int) -> can.Message:
    """An error frame as python-can's socketcan delivers it: the class in the id, no CAN_ERR_FLAG."""
    return can.Message(
        timestamp=t_ns / NS_PER_S,
        arbitration_id=error_class,
        is_error_frame=True,
        is_extended_id=False,
        data=bytes(_ERROR_FRAME_DLC),
    )


class BusOffRoverEnd(can.BusABC):
    """The rover's end of an in-process CAN bus; bus-off while the schedule's ``can`` ``off`` is active.

    ``refused`` counts the sends refused, ``unheard`` the frames the rover missed while bus-off.
    """

    def __init__(self, inner: can.BusABC, faults: FaultSchedule, clock: Clock) -> None:
        super().__init__(channel=getattr(inner, "channel_info", "bus-off"))
        self.channel_info = f"bus-off:{inner.channel_info}"
        self._inner = inner
        self._faults = faults
        self._clock = clock
        self._off = False
        self._error_frames: deque[can.Message] = deque()
        self.refused = 0
        self.unheard = 0

    @property
    def off(self) -> bool:
        """Whether the rover's controller is bus-off now (noting the change's error frame if it changed)."""
        now = self._clock.now_ns()
        off = self._faults.active("can", now, "off") is not None
        if off != self._off:
            self._off = off
            self._error_frames.append(error_frame(CAN_ERR_BUSOFF if off else CAN_ERR_RESTARTED, now))
        return off

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self.off:
            self.refused += 1
            raise can.CanOperationError(
                "simulated bus-off: the rover's CAN controller left the bus (no ACK, transmit error "
                "counter past 255) and refuses to transmit"
            )
        self._inner.send(msg, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        off = self.off
        if self._error_frames:
            return self._error_frames.popleft(), False
        if off:
            # A bus-off controller hears nothing; what the controllers sent meanwhile is lost to the rover.
            while self._inner.recv(timeout=0) is not None:
                self.unheard += 1
            return None, False
        # Lockstep: nothing arrives while one waits (one thread owns both ends), so never block.
        return self._inner.recv(timeout=0), False

    def shutdown(self) -> None:
        # The inner bus belongs to the lockstep wiring, which shuts it; this wrapper is the world's.
        super().shutdown()
