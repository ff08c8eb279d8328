"""What the control tick reads of the wheel controllers' readings, built once per CAN snapshot.

The onboard stack (``navigator.onboard``) builds a ``WheelSnapshot`` from the link's ``WheelStatus`` each
time a poll brought frames; the start-up checks, the estimator and the safety inputs all read that one
snapshot in the tick.
"""

from __future__ import annotations

from typing import NamedTuple

from firmware_bridge.can_link import WheelStatus


class WheelSnapshot(NamedTuple):
    """What the tick reads of one snapshot of the wheel controllers' readings, built once per snapshot
    (the start-up checks, the estimator and the safety inputs all read it)."""

    status_ns: tuple[int | None, ...]  # each controller's last STATUS time, None: never heard
    heard: bool  # every controller heard
    # For the stall check: a controller never heard has no speed or current to judge (wheel_silent covers
    # it): 0.0, not stalled. With every controller heard (when the estimator reads them), the speeds as
    # reported.
    judged_speeds_mps: tuple[float, ...]
    judged_currents_a: tuple[float, ...]
    battery_v: float | None  # the lowest pack voltage reported (None: no controller reported one yet)

    @classmethod
    def of(cls, status: WheelStatus) -> WheelSnapshot:
        # The link's tuples taken as they are (CanLink.wheel_status builds them once per poll): nothing
        # read wheel by wheel in the usual case.
        status_ns = status.status_ns
        heard = None not in status_ns
        voltages = status.input_voltages_v
        lowest_v = min(voltages) if voltages else None
        if lowest_v is not None and not lowest_v > 0.0:
            # Some controller reported no voltage (yet): the lowest of those that did.
            reported = [v for v in voltages if v > 0.0]
            lowest_v = min(reported) if reported else None
        if heard:  # the usual case: the speeds and currents as reported
            return cls(status_ns, heard, status.speeds_mps, status.motor_currents_a, lowest_v)
        return cls(
            status_ns,
            heard,
            tuple([v if t is not None else 0.0 for v, t in zip(status.speeds_mps, status_ns, strict=True)]),
            tuple(
                [a if t is not None else 0.0 for a, t in zip(status.motor_currents_a, status_ns, strict=True)]
            ),
            lowest_v,
        )
