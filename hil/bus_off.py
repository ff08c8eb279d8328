"""The rover's own CAN controller going bus-off during a ``can`` ``off`` fault, in lockstep and real time.

A bus-off is the rover's controller's state, not only the wire's: with no ACK (a cut or shorted bus) its
transmit error counter passes 255 and it leaves the bus. Its host then cannot send (socketcan refuses with
ENOBUFS / ENETDOWN, which python-can raises as ``CanOperationError``) and hears nothing, and Linux delivers
a ``CAN_ERR_BUSOFF`` error frame (python-can's socketcan bus asks for error frames by default); when the
controller restarts (``ip link ... restart-ms``), a ``CAN_ERR_RESTARTED`` one. The simulator's end of the
bus (``hil.fault_links.FaultyCanBus``) drops the frames on the wire; this module gives the rover's end the
rest, so the rover's link meets what it would meet on the vehicle and its ``can_bus_off`` failsafe fires.
``BusOffEdges`` says when the controller leaves and rejoins the bus and builds the error frame of each
change; two ends use it:

- ``BusOffRoverEnd`` (lockstep, where one process holds both ends: ``hil.world.SimWorld.rover_can_end``)
  wraps the rover's end itself: its sends fail, it hears only the error frames.
- ``BusOffAnnouncer`` (the real-time peer, ``hil.world.SimWorld.announce_bus_off``), where the rover's end
  is another process's: the peer sends the error frames onto the shared bus (python-can's
  ``udp_multicast`` carries ``is_error_frame``, and echoes it to the peer, whose VESCs ignore error
  frames; on ``vcan``, python-can's socketcan sends it with ``CAN_ERR_FLAG`` and Linux should deliver it to
  the sockets that asked for error frames, not tried here: this kernel has no CAN). The rover's
  sends still succeed there and are dropped at the peer; its link withholds them itself once bus-off
  (``counters.withheld``), so only the rounds before it heard the frame go out.

Simplified: a real controller's transmit queue takes a few frames before it refuses (socketcan's
``txqueuelen``, 10 by default) and sends them after the restart; in lockstep every send during the fault
fails.
"""

from __future__ import annotations

import logging
from collections import deque

import can

from firmware_bridge.can_health import CAN_ERR_BUSOFF, CAN_ERR_RESTARTED
from hil.faults import FaultSchedule
from logs.clock import NS_PER_S, Clock

_log = logging.getLogger(__name__)

_ERROR_FRAME_DLC = 8  # Linux's CAN_ERR_DLC
# How often the real-time peer repeats CAN_ERR_BUSOFF while the fault lasts. Linux says it once, to a host
# that cannot miss it; across processes the rover may not be listening yet (it starts after the peer, and
# a fault may be active from the peer's start) or may lose a datagram. On a real bus such a host would
# learn from its failing sends; the link's own threshold for that is 0.1 s (``safety.can_fail_s``), so
# a repeat every 0.1 s tells it as soon.
BUS_OFF_REPEAT_NS = 100_000_000
# What a refused send raises with (``can.CanOperationError``); the replay's end of a recorded bus-off says
# the same (hil.replay_bus_off), so a link that logs it logs the same line.
BUS_OFF_REFUSAL = (
    "simulated bus-off: the rover's CAN controller left the bus (no ACK, transmit error counter past 255) "
    "and refuses to transmit"
)


def error_frame(error_class: int, t_ns: int) -> can.Message:
    """An error frame as python-can's socketcan delivers it: the class in the id, no CAN_ERR_FLAG."""
    return can.Message(
        timestamp=t_ns / NS_PER_S,
        arbitration_id=error_class,
        is_error_frame=True,
        is_extended_id=False,
        data=bytes(_ERROR_FRAME_DLC),
    )


class BusOffEdges:
    """When the rover's controller leaves the bus and rejoins it: while any ``can`` ``off`` is active.

    Overlapping or back-to-back faults are one bus-off, from the first start to the last end, as the
    controller cannot leave the bus twice. A fault already active at the first look is a change too.
    """

    def __init__(self, faults: FaultSchedule) -> None:
        self._faults = faults
        self.off = False

    def change(self, now_ns: int) -> can.Message | None:
        """The error frame Linux delivers for a change of state at ``now_ns``; None if it did not change."""
        off = self._faults.active("can", now_ns, "off") is not None
        if off == self.off:
            return None
        self.off = off
        return error_frame(CAN_ERR_BUSOFF if off else CAN_ERR_RESTARTED, now_ns)


class BusOffRoverEnd(can.BusABC):
    """The rover's end of an in-process CAN bus; bus-off while the schedule's ``can`` ``off`` is active.

    ``refused`` counts the sends refused, ``unheard`` the frames the rover missed while bus-off.
    """

    def __init__(self, inner: can.BusABC, faults: FaultSchedule, clock: Clock) -> None:
        super().__init__(channel=getattr(inner, "channel_info", "bus-off"))
        self.channel_info = f"bus-off:{inner.channel_info}"
        self._inner = inner
        self._edges = BusOffEdges(faults)
        self._clock = clock
        self._error_frames: deque[can.Message] = deque()
        self.refused = 0
        self.unheard = 0

    @property
    def off(self) -> bool:
        """Whether the rover's controller is bus-off now (noting the change's error frame if it changed)."""
        changed = self._edges.change(self._clock.now_ns())
        if changed is not None:
            self._error_frames.append(changed)
        return self._edges.off

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self.off:
            self.refused += 1
            raise can.CanOperationError(BUS_OFF_REFUSAL)
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


class BusOffAnnouncer:
    """The real-time peer's word to the rover, on the shared bus, that the rover's controller is bus-off.

    ``poll(now_ns)`` every physics step: on a change it sends the error frame ``BusOffEdges`` builds, and
    while the bus-off lasts it repeats ``CAN_ERR_BUSOFF`` every ``repeat_ns`` for a rover that missed it.
    The frames go straight onto ``bus``, the peer's raw end, not through the fault wrapper: an error frame
    is the controller's report to its own host, which no fault on the wire drops or delays. A failed send
    is counted and logged; a lost ``CAN_ERR_RESTARTED`` heals itself, as the rover's link also takes the
    controllers' frames coming back as the bus's restart (``BusStateMachine.on_frame_received``).
    """

    def __init__(self, bus: can.BusABC, faults: FaultSchedule, repeat_ns: int = BUS_OFF_REPEAT_NS) -> None:
        if repeat_ns <= 0:
            raise ValueError(f"bus-off repeat period must be positive, got {repeat_ns} ns")
        self._bus = bus
        self._edges = BusOffEdges(faults)
        self._repeat_ns = repeat_ns
        self._last_sent_ns = 0
        self.sent = 0  # error frames put on the bus, repeats included
        self.repeats = 0
        self.send_errors = 0

    def poll(self, now_ns: int) -> None:
        frame = self._edges.change(now_ns)
        if frame is None and self._edges.off and now_ns - self._last_sent_ns >= self._repeat_ns:
            frame = error_frame(CAN_ERR_BUSOFF, now_ns)
            self.repeats += 1
        if frame is not None:
            self._send(frame, now_ns)

    def summary(self) -> dict[str, int]:
        """What was announced: for the peer's status file, its recording and its closing line."""
        return {"error_frames_sent": self.sent, "repeats": self.repeats, "send_errors": self.send_errors}

    def _send(self, frame: can.Message, now_ns: int) -> None:
        self._last_sent_ns = now_ns
        try:
            self._bus.send(frame)
        except can.CanError as err:
            self.send_errors += 1
            _log.warning("could not tell the rover CAN error 0x%x: %s", frame.arbitration_id, err)
            return
        self.sent += 1
