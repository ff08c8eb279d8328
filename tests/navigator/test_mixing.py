import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from navigator.errors import ParameterError
from navigator.mixing import mix_skid_steer, unmix_skid_steer
from navigator.vehicle import VehicleParams

PARAMS = VehicleParams()


def test_straight_and_turning():
    assert mix_skid_steer(1.0, 0.0, PARAMS) == [1.0] * 6
    wheels = mix_skid_steer(0.0, 1.0, PARAMS)
    half = 0.5 * 0.55 * 1.6
    assert wheels == pytest.approx([-half] * 3 + [half] * 3)  # CCW turn: right side forward


@given(
    speed=st.floats(-3.0, 3.0, allow_nan=False),
    yaw_rate=st.floats(-5.0, 5.0, allow_nan=False),
)
def test_saturation_keeps_curvature_and_limits(speed, yaw_rate):
    wheels = mix_skid_steer(speed, yaw_rate, PARAMS)
    assert max(abs(w) for w in wheels) <= PARAMS.max_wheel_speed_mps + 1e-12
    v, w = unmix_skid_steer(wheels, PARAMS)
    # One common scale factor in (0, 1]: same direction, same curvature (v : w) as asked for.
    assert v * yaw_rate == pytest.approx(w * speed, abs=1e-9)
    assert v * speed >= 0.0 and w * yaw_rate >= 0.0
    assert abs(v) <= abs(speed) + 1e-12 and abs(w) <= abs(yaw_rate) + 1e-12
    half_track = 0.5 * PARAMS.effective_track_m
    if abs(speed) + abs(yaw_rate) * half_track <= PARAMS.max_wheel_speed_mps:
        assert (v, w) == pytest.approx((speed, yaw_rate))


def test_saturated_arc_example():
    wheels = mix_skid_steer(1.5, 1.0, PARAMS)  # right side would need 1.94 m/s
    v, w = unmix_skid_steer(wheels, PARAMS)
    assert max(wheels) == pytest.approx(1.5)
    assert v / w == pytest.approx(1.5)
    assert v < 1.5


def test_bad_input():
    with pytest.raises(ParameterError):
        mix_skid_steer(math.nan, 0.0, PARAMS)
    with pytest.raises(ParameterError, match="6 wheel speeds"):
        unmix_skid_steer([1.0] * 4, PARAMS)
