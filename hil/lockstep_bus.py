"""A two-ended in-process CAN bus for lockstep HIL: python-can's ``BusABC`` without copies or locks.

python-can's ``virtual`` interface deep-copies every frame for every receiver and passes it through a
thread-safe ``queue.Queue``; in a lockstep trial, where one thread owns both ends and nobody mutates a
frame after sending it, that was the largest single cost per frame (profiled: ~40 % of the CAN time). Here
``send`` appends the frame object to the peer's ``deque`` and ``recv`` pops it: the same frames, in the same
order, with the same python-can API on both ends (filters, ``recv(timeout)``, ``shutdown``). It is also a
``firmware_bridge.can_bus.BatchBus``: ``send_all`` and ``recv_all`` move a whole batch (a command round, a
status period's 6-18 frames, everything waiting) in one call, as ``send`` and ``recv(timeout=0)`` would
one frame at a time.

Frames are stamped with the send-side ``Clock`` (seconds), not the wall clock, so a lockstep run stays
deterministic; our CAN link records its own clock's time anyway.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
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
        self.send_all((msg,))

    def send_all(self, msgs: Sequence[can.Message]) -> None:
        """``send`` of each frame in turn, in one call; all of them or, shut down, none (the error).

        Hot path (the simulated controllers' status frames and the link's command rounds, ~720 frames per
        simulated second): the checks, the clock reading and the counting are done once per batch. The
        frames of one batch share the send time: one caller sends them at one instant of its clock."""
        if not self._open:
            raise can.CanOperationError(f"lockstep CAN bus {self.channel_info} is shut down")
        peer = self._peer
        if peer is not None and peer._open:
            # One thread owns both ends and frames are never mutated after sending: no copy needed. The
            # timestamp is set on the frame itself, as python-can's virtual bus does on its copy.
            channel = self.channel_info
            if self._clock is None:
                for msg in msgs:
                    msg.channel = channel
            else:
                timestamp = self._clock.now_ns() / 1e9
                for msg in msgs:
                    msg.timestamp = timestamp
                    msg.channel = channel
            peer._incoming.extend(msgs)
        self.frames_sent += len(msgs)

    def recv_all(self) -> Sequence[can.Message]:
        """Every frame ``recv(timeout=0)`` would give, called until it gives None: without filters, all
        that are waiting, in order, in one call (hot path: one call per poll, none per frame, nothing for
        an empty bus); with filters, python-can's recv frame by frame, stopping where it gives None."""
        incoming = self._incoming
        if not incoming:
            return ()  # the usual poll of the simulated controllers: no command this tick
        if self._filters is None:
            waiting = list(incoming)
            incoming.clear()
            return waiting
        frames: list[can.Message] = []
        while (msg := self.recv(timeout=0)) is not None:
            frames.append(msg)
        return frames

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
