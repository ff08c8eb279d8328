"""Wheel-speed transients: a launch or a hard stop is seen, encoder noise and gentle ramps are not."""

from __future__ import annotations

import numpy as np

from estimator.transient import WheelTransient

STEP_NS = 20_000_000  # 50 Hz wheel status


def _feed(detector: WheelTransient, speeds: list[float]) -> list[bool]:
    unsettled = []
    for k, speed in enumerate(speeds):
        t = k * STEP_NS
        detector.add(t, speed)
        unsettled.append(detector.unsettled(t))
    return unsettled


def test_a_launch_is_a_transient_until_it_has_settled():
    # Standing for 1 s, wheels spun up to 0.8 m/s within 0.1 s, then steady for 3 s.
    speeds = [0.0] * 50 + [0.16 * i for i in range(1, 6)] + [0.8] * 150
    unsettled = _feed(WheelTransient(accel_limit_mps2=1.0, settle_s=1.0), speeds)
    assert not any(unsettled[:50])
    assert unsettled[51]  # the spread in the window passes 0.25 m/s on the second rising sample
    last_change = 54
    settled_at = last_change + round(1.0e9 / STEP_NS) + round(0.25e9 / STEP_NS)
    assert all(unsettled[51 : settled_at - 2])
    assert not any(unsettled[settled_at + 1 :])


def test_encoder_noise_and_a_gentle_ramp_are_steady():
    rng = np.random.default_rng(3)
    noisy = (0.8 + rng.normal(0.0, 0.035, 3000)).tolist()  # rocky-ground wheel noise, a minute
    ramp = [0.8 - 0.4 * k * STEP_NS * 1e-9 for k in range(100)]  # 0.4 m/s^2 for 2 s
    detector = WheelTransient(accel_limit_mps2=1.0, settle_s=1.0)
    assert not any(_feed(detector, noisy + ramp))


def test_late_or_repeated_samples_change_nothing():
    detector = WheelTransient(accel_limit_mps2=1.0, settle_s=1.0)
    detector.add(1_000_000_000, 0.8)
    detector.add(900_000_000, 0.0)  # older than the last: ignored, not a 0.8 m/s drop
    detector.add(1_000_000_000, 0.0)  # same time again: ignored
    assert not detector.unsettled(1_000_000_000)
