"""The health of the CAN link: bus state (from error frames and the interface), per-controller liveness,
and the bus load the link measures itself (``can/stats``).

Error frames follow Linux SocketCAN's layout (``linux/can/error.h``): the error class is in the
arbitration id, controller status details in data byte 1. python-can delivers them with
``is_error_frame`` set; interfaces that track the state themselves report it through ``bus.state``.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import can

from firmware_bridge.wheel_names import wheel_label
from logs.can_load import WINDOW_NS
from logs.topics import stamp

_NEVER_NS = 1 << 63  # a log time no run reaches

# Error classes (arbitration id bits of an error frame).
CAN_ERR_CRTL = 0x0004  # controller problem, details in data[1]
CAN_ERR_BUSOFF = 0x0040
CAN_ERR_RESTARTED = 0x0100  # the controller was restarted after bus-off
# data[1] bits of a CAN_ERR_CRTL frame.
CAN_ERR_CRTL_RX_PASSIVE = 0x10
CAN_ERR_CRTL_TX_PASSIVE = 0x20
CAN_ERR_CRTL_ACTIVE = 0x40  # back to error-active


class CanLinkState(enum.Enum):
    """What the link may do with wheel commands.

    OK: commands go out. ERROR_PASSIVE: the bus is unreliable, zeros go out instead. BUS_OFF: the controller
    cannot transmit, nothing goes out (the motor controllers' own timeout stops the wheels). RECOVERING: the
    bus is back, zeros go out until every motor controller has been heard again.
    """

    OK = "ok"
    ERROR_PASSIVE = "error_passive"
    BUS_OFF = "bus_off"
    RECOVERING = "recovering"


class BusSignal(enum.Enum):
    """What one error frame (or a ``bus.state`` reading) says about the bus."""

    NONE = "none"  # a bus error worth counting, no change of state
    ERROR_PASSIVE = "error_passive"
    BUS_OFF = "bus_off"
    BACK = "back"  # restarted after bus-off, or error-active again


def classify_error_frame(msg: can.Message) -> BusSignal:
    """The state change an error frame announces, if any."""
    error_class = msg.arbitration_id
    if error_class & CAN_ERR_BUSOFF:
        return BusSignal.BUS_OFF
    if error_class & CAN_ERR_RESTARTED:
        return BusSignal.BACK
    if error_class & CAN_ERR_CRTL and len(msg.data) > 1:
        status = msg.data[1]
        if status & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE):
            return BusSignal.ERROR_PASSIVE
        if status & CAN_ERR_CRTL_ACTIVE:
            return BusSignal.BACK
    return BusSignal.NONE


def classify_bus_state(state: can.BusState) -> BusSignal:
    """``bus.state`` of interfaces that track it (PCAN, Kvaser...); socketcan and virtual say ACTIVE."""
    if state is can.BusState.ERROR:
        return BusSignal.BUS_OFF
    if state is can.BusState.PASSIVE:
        return BusSignal.ERROR_PASSIVE
    return BusSignal.NONE


@dataclass(frozen=True)
class StateChange:
    """A transition to report on ``safety/events``."""

    kind: str
    severity: str
    detail: str


class BusStateMachine:
    """OK -> ERROR_PASSIVE / BUS_OFF on a fault; -> RECOVERING when the bus is back; -> OK once every
    controller has sent a status since the recovery began. Pure: the link feeds it and publishes."""

    def __init__(self, controller_ids: Sequence[int]) -> None:
        self._ids = frozenset(controller_ids)
        self.state = CanLinkState.OK
        self._heard_since_recovery: set[int] = set()

    def on_signal(self, signal: BusSignal, cause: str) -> StateChange | None:
        if signal is BusSignal.BUS_OFF and self.state is not CanLinkState.BUS_OFF:
            self.state = CanLinkState.BUS_OFF
            return StateChange("can_bus_off", "error", f"CAN bus-off ({cause}); wheel commands stopped")
        if signal is BusSignal.ERROR_PASSIVE and self.state in (CanLinkState.OK, CanLinkState.RECOVERING):
            self.state = CanLinkState.ERROR_PASSIVE
            return StateChange(
                "can_error_passive", "warning", f"CAN error-passive ({cause}); commanding zero wheel speed"
            )
        if signal is BusSignal.BACK and self.state in (CanLinkState.BUS_OFF, CanLinkState.ERROR_PASSIVE):
            return self._start_recovery(cause)
        return None

    def on_frame_received(self) -> StateChange | None:
        """A valid frame arrived: a bus-off controller receives nothing, so the bus is back."""
        if self.state is CanLinkState.BUS_OFF:
            return self._start_recovery("frames received again")
        return None

    def on_status(self, controller_id: int) -> StateChange | None:
        if self.state is not CanLinkState.RECOVERING:
            return None
        self._heard_since_recovery.add(controller_id)
        if self._heard_since_recovery >= self._ids:
            self.state = CanLinkState.OK
            return StateChange(
                "can_recovered", "info", "every motor controller reported again; wheel commands resumed"
            )
        return None

    def _start_recovery(self, cause: str) -> StateChange:
        self.state = CanLinkState.RECOVERING
        self._heard_since_recovery = set()
        return StateChange(
            "can_recovering",
            "warning",
            f"CAN bus back ({cause}); commanding zero until all {len(self._ids)} controllers report",
        )


class ControllerLiveness:
    """A controller is alive while its STATUS keeps coming: silent for ``silent_after_ns`` means a fault.

    Until a controller is first heard, the silence is counted from ``start_ns`` (or from ``start()``).
    """

    def __init__(self, controller_ids: Sequence[int], silent_after_ns: int, start_ns: int) -> None:
        self._ids = tuple(controller_ids)
        self._silent_after_ns = silent_after_ns
        self._last_heard = dict.fromkeys(self._ids, start_ns)
        self._alive = dict.fromkeys(self._ids, True)
        # Until this time no living controller can have been silent too long: the earliest of their last
        # hearings plus the limit, as the last full check found it (hearings only move later). check()
        # runs at every poll, and before this time it has nothing to look at.
        self._quiet_until_ns = start_ns + silent_after_ns

    def start(self, now_ns: int) -> None:
        """Count silence from ``now_ns`` for every controller not heard since (the watch's real start)."""
        self._last_heard = {cid: max(t, now_ns) for cid, t in self._last_heard.items()}

    def heard(self, controller_id: int, t_ns: int) -> StateChange | None:
        self._last_heard[controller_id] = t_ns
        if self._alive[controller_id]:
            return None
        self._alive[controller_id] = True
        self._quiet_until_ns = min(self._quiet_until_ns, t_ns + self._silent_after_ns)
        return StateChange(
            "can_controller_alive", "info", f"motor controller of {self._label(controller_id)} reports again"
        )

    def check(self, now_ns: int) -> list[StateChange]:
        if now_ns <= self._quiet_until_ns:
            return []
        changes: list[StateChange] = []
        for cid in self._ids:
            silence = now_ns - self._last_heard[cid]
            if self._alive[cid] and silence > self._silent_after_ns:
                self._alive[cid] = False
                changes.append(
                    StateChange(
                        "can_controller_silent",
                        "error",
                        f"motor controller of {self._label(cid)} silent for {silence / 1e6:.0f} ms "
                        f"(limit {self._silent_after_ns / 1e6:.0f} ms)",
                    )
                )
        living = [self._last_heard[cid] for cid in self._ids if self._alive[cid]]
        # None alive: nothing to check until one reports again (heard() brings this time back then).
        self._quiet_until_ns = min(living) + self._silent_after_ns if living else _NEVER_NS
        return changes

    def alive(self) -> dict[int, bool]:
        return dict(self._alive)

    def _label(self, controller_id: int) -> str:
        return wheel_label(self._ids.index(controller_id), self._ids)


class BusLoadMeter:
    """One ``can/stats`` message per window of log time, from the link's running counters.

    The link sees every frame on the bus (it sends the commands and receives everything else), so its
    count is right wherever the recorded or streamed ``can/frames`` are thinned. Pure: the link counts bits
    per frame and asks ``message()`` at the first poll at or after ``due_ns``, which closes the window
    (``window_s`` is the real length).
    """

    def __init__(self, bitrate: int, start_ns: int, window_ns: int = WINDOW_NS) -> None:
        self._bitrate = bitrate
        self._window_ns = window_ns
        self._start_ns = start_ns
        self._frames_at_start = 0
        self._bits_at_start = 0
        self.due_ns = start_ns + window_ns  # message() gives the window's stats from this log time on

    def restart(self, now_ns: int, *, frames_total: int, bits_total: int) -> None:
        """Open a new window at ``now_ns`` from the link's running totals, discarding the open one: the link
        does it when its loop starts, so the first window measures the running bus, not a start-up
        during which nothing is sent (which could last longer than a window)."""
        self._start_ns = now_ns
        self._frames_at_start = frames_total
        self._bits_at_start = bits_total
        self.due_ns = now_ns + self._window_ns

    def message(
        self,
        now_ns: int,
        *,
        tx_total: int,
        rx_total: int,
        bits_total: int,
        own_echoes_total: int,
        link_counters: Callable[[], Mapping[str, int]],
    ) -> dict[str, Any] | None:
        """The window's stats if it is over (``now_ns >= due_ns``), else ``None``. ``link_counters`` is
        asked only then: building the counters' dict at every poll was a measurable share of the lockstep
        trial's CAN time."""
        if now_ns < self.due_ns:
            return None
        elapsed_ns = now_ns - self._start_ns
        frames_total = tx_total + rx_total
        frames = frames_total - self._frames_at_start
        bits = bits_total - self._bits_at_start
        window_s = elapsed_ns / 1e9
        self._start_ns = now_ns
        self._frames_at_start = frames_total
        self._bits_at_start = bits_total
        self.due_ns = now_ns + self._window_ns
        return {
            "timestamp": stamp(now_ns),
            "window_s": window_s,
            "bitrate": self._bitrate,
            "frames": frames,
            "bits": bits,
            "load_pct": 100.0 * bits / window_s / self._bitrate,
            "tx_total": tx_total,
            "rx_total": rx_total,
            "own_echoes_total": own_echoes_total,
            "link_counters": dict(link_counters()),
        }
