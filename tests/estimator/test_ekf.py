import math

import numpy as np
import pytest

from estimator.angles import wrap_angle
from estimator.config import EstimatorConfig
from estimator.ekf import BIAS, SPEED, YAW, YAW_RATE, RoverEkf
from estimator.errors import EstimatorOperationError

S = 1_000_000_000


def _ekf(yaw: float = 0.0) -> RoverEkf:
    ekf = RoverEkf(EstimatorConfig())
    ekf.initialise(0.0, 0.0, yaw, 0, position_std_m=0.5, yaw_std_rad=0.05)
    return ekf


def test_wrap_angle_range():
    assert wrap_angle(math.pi) == math.pi
    assert wrap_angle(-math.pi) == math.pi
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert wrap_angle(-7.0) == pytest.approx(-7.0 + 2 * math.pi)


def test_use_before_initialise_is_a_typed_error():
    ekf = RoverEkf(EstimatorConfig())
    with pytest.raises(EstimatorOperationError, match="initialise"):
        ekf.predict(10)
    with pytest.raises(EstimatorOperationError):
        ekf.update_gyro(0.0)


def test_predict_drives_along_the_heading_and_turns():
    ekf = _ekf(yaw=math.pi / 2)
    ekf.update_odometry(1.0, 0.0, 0.01, 0.01)
    for k in range(1, 51):
        ekf.predict(k * 20_000_000)
    x = ekf.x
    assert x[0] == pytest.approx(0.0, abs=0.05)
    assert x[1] == pytest.approx(x[SPEED] * 1.0, rel=1e-6)
    assert x[SPEED] > 0.9


def test_constant_turn_matches_the_circle():
    ekf = _ekf()
    ekf.update_odometry(1.0, 0.5, 1e-4, 1e-4)
    v, w = ekf.state(SPEED), ekf.state(YAW_RATE)
    for k in range(1, 101):
        ekf.predict(k * 20_000_000)
    t = 2.0
    expected = (v / w * math.sin(w * t), v / w * (1.0 - math.cos(w * t)))
    assert ekf.x[:2] == pytest.approx(expected, abs=1e-3)
    assert ekf.state(YAW) == pytest.approx(wrap_angle(w * t))


def test_predict_backwards_or_same_time_changes_nothing():
    ekf = _ekf()
    ekf.predict(S)
    x, p = ekf.x, ekf.covariance
    ekf.predict(S)
    ekf.predict(S // 2)
    assert np.array_equal(ekf.x, x)
    assert np.array_equal(ekf.covariance, p)
    assert ekf.t_ns == S


def test_process_noise_grows_uncertainty_with_time():
    ekf = _ekf()
    before = ekf.covariance
    ekf.predict(S)
    after = ekf.covariance
    assert after[SPEED, SPEED] == pytest.approx(before[SPEED, SPEED] + 0.5**2)
    assert after[BIAS, BIAS] > before[BIAS, BIAS]


def test_gyro_measures_rate_plus_bias():
    ekf = _ekf()
    innovation = ekf.update_gyro(0.2)
    assert innovation.accepted
    assert innovation.residual == pytest.approx((0.2,))
    assert ekf.state(YAW_RATE) + ekf.state(BIAS) == pytest.approx(0.2, abs=0.01)


def test_gate_rejects_outlier_and_leaves_state_untouched():
    ekf = _ekf()
    x, p = ekf.x, ekf.covariance
    innovation = ekf.update_position(50.0, 0.0, 0.5)
    assert not innovation.accepted
    assert innovation.nis > 1000.0
    assert np.array_equal(ekf.x, x)
    assert np.array_equal(ekf.covariance, p)


def test_ungated_update_is_applied():
    ekf = _ekf()
    assert ekf.update_position(50.0, 0.0, 0.5, gated=False).accepted
    assert ekf.state(0) > 10.0


def test_heading_update_wraps_across_pi():
    ekf = _ekf(yaw=math.pi - 0.05)
    innovation = ekf.update_heading(-math.pi + 0.05, 0.05)
    assert innovation.accepted
    assert innovation.residual[0] == pytest.approx(0.1)
    assert abs(ekf.state(YAW)) > math.pi - 0.06  # moved across pi, not the long way round


def test_covariance_stays_symmetric_positive_definite():
    rng = np.random.default_rng(3)
    ekf = _ekf()
    for k in range(1, 500):
        ekf.predict(k * 20_000_000)
        ekf.update_gyro(float(rng.normal(0.1, 0.01)))
        ekf.update_odometry(float(rng.normal(1.0, 0.05)), float(rng.normal(0.1, 0.05)), 0.05, 0.05)
        if k % 10 == 0:
            ekf.update_position(float(rng.normal(0, 0.5)), float(rng.normal(0, 0.5)), 0.5, gated=False)
    p = ekf.covariance
    assert np.allclose(p, p.T)
    assert np.all(np.linalg.eigvalsh(p) > 0.0)


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_measurements_are_typed_errors(bad):
    ekf = _ekf()
    with pytest.raises(EstimatorOperationError, match="finite"):
        ekf.update_position(bad, 0.0, 0.5)
    with pytest.raises(EstimatorOperationError, match="std"):
        ekf.update_odometry(1.0, 0.0, 0.0, 0.1)


@pytest.mark.parametrize("learning", [True, False])
def test_update_at_a_time_is_predict_then_update_to_the_bit(learning):
    """``update_*(..., t_ns=t)`` (one compiled call) gives the very floats of ``predict(t)`` then the update,
    for the gyro and both odometry forms, while the scale is learnt and while it is only considered."""
    fused, stepwise = _ekf(yaw=0.3), _ekf(yaw=0.3)
    for ekf in (fused, stepwise):
        ekf.learn_scale(learning)
    t = 0
    for k in range(40):
        t += 20_000_000 + 37 * k  # uneven steps
        speed, rate = 0.8 + 0.01 * k, 0.2 - 0.013 * k
        stepwise.predict(t)
        expected = [stepwise.update_gyro(rate + 0.001)]
        got = [fused.update_gyro(rate + 0.001, t_ns=t)]
        t += 3_000_000
        stepwise.predict(t)
        use_speed = k % 3 != 0
        expected.append(stepwise.update_odometry(speed, rate, 0.05, 0.02, use_speed=use_speed))
        got.append(fused.update_odometry(speed, rate, 0.05, 0.02, use_speed=use_speed, t_ns=t))
        assert got == expected
        assert np.array_equal(fused.x, stepwise.x) and np.array_equal(fused.covariance, stepwise.covariance)
        assert fused.t_ns == stepwise.t_ns == t
    # A time not after the filter's own: no prediction, as predict() would do.
    before = fused.x
    fused.update_gyro(float(before[YAW_RATE] + before[BIAS]), t_ns=t - 1)
    assert fused.t_ns == t
