"""The EKF kernels' explicit matrix products against the BLAS products (numba's ``@``) they replaced."""

from __future__ import annotations

import numba
import numpy as np
import pytest

from estimator.ekf import BIAS, SCALE, SPEED, YAW_RATE
from estimator.ekf_kernels import WALK_STATES, _product

Array = np.ndarray


@numba.njit(cache=False)
def _blas_product(a: Array, b: Array) -> Array:
    return a @ b


@numba.njit(cache=False)
def _blas_product_t(a: Array, b: Array) -> Array:
    return a @ b.T


# The shapes the kernels multiply: F P (7x7 7x7), K H (7xm mx7), (I - K H) P, K R (7xm mxm).
SHAPES = [((7, 7), (7, 7)), ((7, 1), (1, 7)), ((7, 2), (2, 7)), ((7, 1), (1, 1)), ((7, 2), (2, 2))]


@pytest.mark.parametrize(("a_shape", "b_shape"), SHAPES)
def test_products_give_the_blas_products_bit_for_bit(
    a_shape: tuple[int, int], b_shape: tuple[int, int]
) -> None:
    # Bit for bit, not close: the recorded trials must not change (the same sums in the same order).
    rng = np.random.default_rng(7)
    for _ in range(300):
        a = rng.normal(size=a_shape) * rng.uniform(1e-4, 1e3)
        b = rng.normal(size=b_shape) * rng.uniform(1e-4, 1e3)
        np.testing.assert_array_equal(_product(a, b), _blas_product(a, b))
        bt = np.ascontiguousarray(b.T)
        np.testing.assert_array_equal(_product(a, bt.T), _blas_product_t(a, bt))


def test_product_of_a_covariance_propagation_is_the_blas_one() -> None:
    # A predict's F P F^T, with F the identity plus the motion model's few off-diagonal terms.
    rng = np.random.default_rng(11)
    for _ in range(300):
        root = rng.normal(size=(7, 7))
        p = root @ root.T * rng.uniform(1e-6, 10.0)
        f = np.eye(7)
        f[0, 2:5] = rng.normal(size=3) * 0.01
        f[1, 2:5] = rng.normal(size=3) * 0.01
        f[2, 4] = 0.02
        np.testing.assert_array_equal(_product(_product(f, p), f.T), _blas_product_t(_blas_product(f, p), f))


def test_the_kernels_walk_the_states_the_filter_has_noise_intensities_for() -> None:
    # RoverEkf builds q_rate in this order; the kernels read the states from their own constant.
    assert tuple(WALK_STATES) == (SPEED, YAW_RATE, BIAS, SCALE)
