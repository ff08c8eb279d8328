"""The IMU model's plain-float arithmetic gives the numbers its former numpy formulation gave."""

from __future__ import annotations

import numpy as np
import pytest

from hil.faults import Fault, FaultSchedule
from hil.sensors import GpsModel, GpsSample, ImuModel


def _numpy_reading(
    noise: np.random.Generator,
    yaw_rate: float,
    force: tuple[float, float, float],
    gyro_bias: tuple[float, float, float],
    accel_bias: tuple[float, float, float],
    wrong: Fault | None,
) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The reference: the same draws, the sums done on float64 arrays."""
    gyro = np.array([0.0, 0.0, yaw_rate]) + np.asarray(gyro_bias) + noise.normal(0.0, 0.01, 3)
    accel = np.asarray(force, dtype=float) + np.asarray(accel_bias) + noise.normal(0.0, 0.05, 3)
    if wrong is not None:
        gyro = gyro + np.asarray(wrong.gyro_bias_rps)
        accel = accel + np.asarray(wrong.accel_bias_mps2)
    return tuple(float(v) for v in gyro), tuple(float(v) for v in accel)


@pytest.mark.parametrize("with_fault", [False, True])
def test_imu_reading_equals_the_array_formulation(with_fault: bool) -> None:
    wrong = Fault(
        target="imu",
        kind="wrong",
        start_ns=0,
        end_ns=100_000_000_000,
        gyro_bias_rps=(0.1, -0.2, 0.3),
        accel_bias_mps2=(-1.5, 0.25, 2.0e-3),
    )
    faults = FaultSchedule((wrong,) if with_fault else ())
    gyro_bias, accel_bias = (1e-3, -2e-3, 3.3e-3), (0.05, -0.07, 0.011)
    model = ImuModel(
        np.random.default_rng(5),
        faults,
        gyro_noise_rps=0.01,
        accel_noise_mps2=0.05,
        gyro_bias_rps=gyro_bias,
        accel_bias_mps2=accel_bias,
    )
    reference = np.random.default_rng(5)
    inputs = np.random.default_rng(9)
    for tick in range(500):
        yaw_rate = float(inputs.normal(0.0, 0.5))
        force = (float(inputs.normal()), float(inputs.normal()), 9.81 + float(inputs.normal(0.0, 0.1)))
        reading = model.read(tick * 20_000_000, yaw_rate, force)
        assert reading is not None
        expected = _numpy_reading(
            reference, yaw_rate, force, gyro_bias, accel_bias, wrong if with_fault else None
        )
        assert (reading.gyro_flu_rps, reading.accel_flu_mps2) == expected  # exactly, not approximately


def _numpy_fix_position(
    noise: np.random.Generator, truth: GpsSample, noise_m: float, wrong: Fault | None
) -> tuple[float, float, float]:
    """The reference: the fix's noise as it was drawn and scaled on arrays (east, north, up x 2)."""
    scaled = noise.normal(0.0, 1.0, 3) * np.array([1.0, 1.0, 2.0]) * noise_m
    noise.random()  # the dropout draw
    x, y, z = truth.x_m + float(scaled[0]), truth.y_m + float(scaled[1]), truth.z_m + float(scaled[2])
    if wrong is not None:
        x += wrong.offset_m[0]
        y += wrong.offset_m[1]
    return x, y, z


@pytest.mark.parametrize("with_fault", [False, True])
def test_gps_fix_equals_the_array_formulation(with_fault: bool) -> None:
    wrong = Fault(target="gps", kind="wrong", start_ns=0, end_ns=100_000_000_000, offset_m=(3.0, -1.25))
    model = GpsModel(np.random.default_rng(5), FaultSchedule((wrong,) if with_fault else ()), noise_m=0.7)
    reference = np.random.default_rng(5)
    inputs = np.random.default_rng(9)
    for tick in range(300):
        now = tick * 200_000_000
        truth = GpsSample(now, *(float(v) for v in inputs.normal(0.0, 50.0, 5)))
        model.record(truth)
        fix = model.fix(now)
        assert fix is not None
        expected = _numpy_fix_position(reference, truth, 0.7, wrong if with_fault else None)
        assert (fix.x_m, fix.y_m, fix.z_m) == expected  # exactly, not approximately
