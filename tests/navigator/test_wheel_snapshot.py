"""The control tick's wheel snapshot: built from the link's ``WheelStatus`` tuples, it gives what a plain
reading of the readings' fields gives."""

from __future__ import annotations

import math

import pytest

from firmware_bridge.can_link import WheelReading, WheelStatus
from navigator.wheel_snapshot import WheelSnapshot


def _reference(readings: list[WheelReading]) -> tuple[object, ...]:
    """The snapshot's meaning, field by field, written the plain way."""
    status = tuple(r.last_status_ns for r in readings)
    heard = None not in status
    speeds = tuple(r.speed_mps if r.last_status_ns is not None else 0.0 for r in readings)
    currents = tuple(r.motor_current_a if r.last_status_ns is not None else 0.0 for r in readings)
    voltages = [r.input_voltage_v for r in readings if r.input_voltage_v > 0.0]
    return status, heard, speeds, currents, min(voltages) if voltages else None


def _readings(voltages: list[float], heard: list[bool]) -> list[WheelReading]:
    return [
        WheelReading(
            controller_id=index + 1,
            speed_mps=0.1 * (index + 1),
            motor_current_a=1.5 * index,
            input_voltage_v=volts,
            last_status_ns=1_000 * index if was_heard else None,
        )
        for index, (volts, was_heard) in enumerate(zip(voltages, heard, strict=True))
    ]


def _status(readings: list[WheelReading]) -> WheelStatus:
    """``CanLink.wheel_status`` of these readings, written the plain way."""
    return WheelStatus(
        tuple(r.last_status_ns for r in readings),
        tuple(r.speed_mps for r in readings),
        tuple(r.motor_current_a for r in readings),
        tuple(r.input_voltage_v for r in readings),
    )


ALL = [True] * 6


@pytest.mark.parametrize(
    ("voltages", "heard"),
    [
        ([24.0, 23.5, 24.1, 23.9, 24.0, 23.8], ALL),  # the usual tick
        ([24.0, 0.0, 24.1, 23.9, 24.0, 23.8], ALL),  # one controller has reported no voltage yet
        ([0.0] * 6, ALL),  # nobody reported one: None
        ([math.nan, 24.0, 23.0, 24.0, 24.0, 24.0], ALL),  # a NaN first: left out, not the minimum
        ([24.0, math.nan, 23.0, 24.0, 24.0, 24.0], ALL),  # a NaN later: left out too
        ([24.0, -3.0, 23.0, 24.0, 24.0, 24.0], ALL),  # a negative reading is no voltage
        ([24.0, 23.5, 24.1, 23.9, 24.0, 23.8], [True, False, True, True, False, True]),  # not all heard
        ([0.0] * 6, [False] * 6),  # nothing heard yet
    ],
)
def test_snapshot_reads_the_fields_as_written(voltages: list[float], heard: list[bool]) -> None:
    readings = _readings(voltages, heard)
    snapshot = WheelSnapshot.of(_status(readings))
    assert tuple(snapshot) == _reference(readings)


def test_no_readings_is_an_empty_snapshot() -> None:
    assert tuple(WheelSnapshot.of(_status([]))) == ((), True, (), (), None)
