"""The ``estimator/pose`` message: the covariance array is encoded as the list of its floats would be."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimator.pose import PoseEstimate, pose_message
from logs.encoding import encode_message


def _pose(covariance: np.ndarray) -> PoseEstimate:
    return PoseEstimate(1.5, -2.25, 0.3, 0.8, -0.05, covariance, True, 5_010_000_000, True, 0.4)


def _as_lists(message: dict) -> dict:
    return {**message, "covariance": np.asarray(message["covariance"]).tolist()}


@pytest.mark.parametrize("seed", range(20))
def test_covariance_array_encodes_as_its_list(seed: int) -> None:
    rng = np.random.default_rng(seed)
    # Magnitudes from tiny to huge (orjson switches to exponents at both ends), and arbitrary bit patterns
    # (subnormals, NaN and infinities among them: null in JSON either way).
    scaled = rng.standard_normal(49) * 10.0 ** rng.integers(-30, 30, 49)
    raw = rng.integers(0, 2**63, 49, dtype=np.int64).view(np.float64)
    for values in (scaled, raw):
        covariance = values.reshape(7, 7).copy()
        covariance.setflags(write=False)  # as the estimator hands it out
        message = pose_message(_pose(covariance))
        assert encode_message(message) == encode_message(_as_lists(message))


def test_special_values_encode_as_their_list() -> None:
    specials = [0.0, -0.0, 1e-5, 1e-7, 1e16, 1e17, 1e21, 5e-324, 0.1, 1 / 3, math.nan, math.inf, -math.inf]
    covariance = np.resize(np.array(specials), 49).reshape(7, 7)
    message = pose_message(_pose(covariance))
    assert encode_message(message) == encode_message(_as_lists(message))


def test_a_transposed_covariance_is_written_in_row_order() -> None:
    """A covariance that is not C-contiguous (a transposed view) still goes out row by row."""
    covariance = np.arange(49.0).reshape(7, 7).T
    message = pose_message(_pose(covariance))
    assert encode_message(message) == encode_message(_as_lists(message))
    assert np.asarray(message["covariance"]).tolist() == covariance.ravel().tolist()
