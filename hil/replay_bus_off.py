"""The replay's rover CAN end, bus-off when the recording says the trial's was (``hil.replay``).

In a lockstep trial with a ``can`` ``off`` fault the rover's end was ``hil.bus_off.BusOffRoverEnd``: its
sends were refused (``can.CanOperationError``, as socketcan refuses a bus-off controller's) from the
fault's start to its end, and it delivered a ``CAN_ERR_BUSOFF`` error frame at the first read into the
fault and a ``CAN_ERR_RESTARTED`` one at the first read after it. The link records those error frames
(``can/frames``, marked "error"); the replay writes them to this end at their recorded times and tells it
(``heard``), so it refuses sends from a BUSOFF to the next RESTARTED. The stack reads its links before it
sends in a tick and nothing else sends between ticks, so no send falls between the fault's start and the
read that took the BUSOFF, nor between its end and the RESTARTED: the same sends are refused.

Only a lockstep trial's end refused sends: under ``rover run`` beside the real-time peer the rover's bus
carried the peer's error frames and took every send, and its link withheld its rounds itself once bus-off
(``CanLink.counters.withheld``), so that replay feeds the error frames on a plain end.
"""

from __future__ import annotations

from collections.abc import Sequence

import can

from firmware_bridge.can_health import CAN_ERR_BUSOFF, CAN_ERR_RESTARTED
from hil.bus_off import BUS_OFF_REFUSAL
from hil.lockstep_bus import LockstepBus


class RecordedBusOffEnd(can.BusABC):
    """Wraps the replay's rover end (a ``LockstepBus``); refuses sends while a recorded bus-off lasts.

    A ``BatchBus`` as its inner bus is, so the link moves its rounds and polls in batches as it does on
    the plain end. ``refused`` counts the frames refused (as ``BusOffRoverEnd`` counts them).
    """

    def __init__(self, inner: LockstepBus) -> None:
        super().__init__(channel=inner.channel_info)
        self.channel_info = f"recorded-bus-off:{inner.channel_info}"
        self._inner = inner
        self.off = False
        self.refused = 0

    def heard(self, error_frame: can.Message) -> None:
        """The controller delivered ``error_frame`` (written to this end): bus-off from a BUSOFF, back on
        the bus from a RESTARTED; any other error class changes nothing here (the link judges it)."""
        error_class = error_frame.arbitration_id
        if error_class & CAN_ERR_BUSOFF:
            self.off = True
        elif error_class & CAN_ERR_RESTARTED:
            self.off = False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self.off:
            self.refused += 1
            # BusOffRoverEnd's words: the link logs a failed send with them, and the replay gives its lines.
            raise can.CanOperationError(BUS_OFF_REFUSAL)
        self._inner.send(msg, timeout)

    def send_all(self, msgs: Sequence[can.Message]) -> None:
        # Refused whole, as a BatchBus may be; the link then sends frame by frame, each refused and counted.
        if self.off:
            raise can.CanOperationError(BUS_OFF_REFUSAL)
        self._inner.send_all(msgs)

    def recv_all(self) -> Sequence[can.Message]:
        return self._inner.recv_all()

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        # Lockstep: nothing arrives while one waits, so never block.
        return self._inner.recv(timeout=0), False

    def pending(self) -> int:
        return self._inner.pending()

    def shutdown(self) -> None:
        # The inner end belongs to the replay's wiring, which shuts it; this wrapper is the link's.
        super().shutdown()
