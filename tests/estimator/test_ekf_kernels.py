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
def test_products_give_the_blas_products(a_shape: tuple[int, int], b_shape: tuple[int, int]) -> None:
    # To the rounding of one sum, not bit for bit: the loops sum in the order OpenBLAS does on the machine
    # they were written on (same bits there), but OpenBLAS picks its kernel by CPU, and a test must not
    # fail on a machine whose BLAS sums in another order.
    rng = np.random.default_rng(7)
    for _ in range(300):
        a = rng.normal(size=a_shape) * rng.uniform(1e-4, 1e3)
        b = rng.normal(size=b_shape) * rng.uniform(1e-4, 1e3)
        _assert_same_product(_product(a, b), _blas_product(a, b), a, b)
        bt = np.ascontiguousarray(b.T)
        _assert_same_product(_product(a, bt.T), _blas_product_t(a, bt), a, b)


def _assert_same_product(ours: Array, blas: Array, a: Array, b: Array) -> None:
    """Equal within the rounding error of a dot product of a's rows with b's columns."""
    bound = 4 * a.shape[1] * np.finfo(np.float64).eps * (np.abs(a) @ np.abs(b))
    assert np.all(np.abs(ours - blas) <= bound)


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
        fp = _blas_product(f, p)
        _assert_same_product(_product(f, p), fp, f, p)
        _assert_same_product(_product(fp, f.T), _blas_product_t(fp, f), fp, f.T)


def test_the_kernels_walk_the_states_the_filter_has_noise_intensities_for() -> None:
    # RoverEkf builds q_rate in this order; the kernels read the states from their own constant.
    assert tuple(WALK_STATES) == (SPEED, YAW_RATE, BIAS, SCALE)
