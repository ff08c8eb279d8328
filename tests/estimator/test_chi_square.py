"""The gate's closed-form chi-square quantiles against scipy's."""

from __future__ import annotations

import pytest
from scipy.stats import chi2

from estimator.chi_square import chi_square_quantile
from estimator.errors import EstimatorSetupError


@pytest.mark.parametrize("dof", [1, 2])
@pytest.mark.parametrize("probability", [0.5, 0.9, 0.95, 0.99, 0.9973, 0.9995, 0.999999])
def test_matches_scipy(probability: float, dof: int) -> None:
    scipy_quantile = float(chi2.ppf(probability, dof))
    assert chi_square_quantile(probability, dof) == pytest.approx(scipy_quantile, rel=1e-12)


@pytest.mark.parametrize(("probability", "dof"), [(0.0, 1), (1.0, 2), (0.99, 3), (0.99, 0)])
def test_refuses_what_it_cannot_give(probability: float, dof: int) -> None:
    with pytest.raises(EstimatorSetupError):
        chi_square_quantile(probability, dof)
