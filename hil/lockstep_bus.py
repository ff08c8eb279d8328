"""A two-ended in-process CAN bus for lockstep HIL: python-can's ``BusABC`` without copies or locks.

python-can's ``virtual`` interface deep-copies every frame for every receiver and passes it through a
thread-safe ``queue.Queue``; in a lockstep trial, where one thread owns both ends and nobody mutates a
frame after sending it, that was the largest single cost per frame (profiled: ~40 % of the CAN time). Here
``send`` appends the frame object to the peer's ``deque`` and ``recv`` pops it: the same frames, in the same
order, with the same python-can API on both ends (filters, ``recv(timeout)``, ``shutdown``).

Frames are stamped with the send-side ``Clock`` (seconds), not the wall clock, so a lockstep run stays
deterministic; our CAN link records its own clock's time anyway.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import can

from logs.clock import Clock


class LockstepBus(can.BusABC):
    """One end of an in-process CAN bus; build a connected pair with ``lockstep_bus_pair``."""

    def __init__(self, channel: str, clock: Clock | None = None, **kwargs: Any) -> None:
        super().__init__(channel=channel, **kwargs)
        self.channel_info = f"lockstep:{channel}"
        self._clock = clock
        self._incoming: deque[can.Message] = deque()
        self._peer: LockstepBus | None = None
        self._open = True
        self.frames_sent = 0

    def _connect(self, peer: LockstepBus) -> None:
        self._peer = peer

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if not self._open:
            raise can.CanOperationError(f"lockstep CAN bus {self.channel_info} is shut down")
        peer = self._peer
        if peer is not None and peer._open:
            # One thread owns both ends and frames are never mutated after sending: no copy needed. The
            # timestamp is set on the frame itself, as python-can's virtual bus does on its copy.
            if self._clock is not None:
                msg.timestamp = self._clock.now_ns() / 1e9
            msg.channel = self.channel_info
            peer._incoming.append(msg)
        self.frames_sent += 1

    def recv(self, timeout: float | None = None) -> can.Message | None:
        # Hot path (~700 frames per simulated second). Without filters, BusABC.recv's wall-clock timeout
        # loop and its per-frame log call have nothing to do here. With filters, or when asked to block,
        # python-can's own recv runs, keeping its semantics (a rejected frame: recv(timeout=0) is None).
        if self._filters is None and timeout is not None:
            incoming = self._incoming
            return incoming.popleft() if incoming else None
        return super().recv(timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        # Lockstep: nothing arrives while we wait, so a timeout could only waste time.
        if self._incoming:
            return self._incoming.popleft(), False
        return None, False

    def pending(self) -> int:
        return len(self._incoming)

    def shutdown(self) -> None:
        self._open = False
        self._incoming.clear()
        super().shutdown()


def lockstep_bus_pair(channel: str, clock: Clock | None = None) -> tuple[LockstepBus, LockstepBus]:
    """Two connected ends: what one sends, the other receives, in order."""
    first = LockstepBus(channel, clock)
    second = LockstepBus(channel, clock)
    first._connect(second)
    second._connect(first)
    return first, second
