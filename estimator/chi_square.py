"""Chi-square quantiles for the EKF's gate, in closed form for the one and two dimensions it needs.

``scipy.stats.chi2.ppf`` gives the same thresholds (to ~1e-14, a test compares them), but importing
``scipy.stats`` costs about two seconds of start-up in every process that builds an estimator
(``rover run``, every trial, every CLI command that imported it); the two quantiles below need only ``math``.
"""

from __future__ import annotations

import math
from statistics import NormalDist

from estimator.errors import EstimatorSetupError


def chi_square_quantile(probability: float, dof: int) -> float:
    """The value a chi-square variable of ``dof`` (1 or 2) degrees of freedom is below with probability ``p``.

    dof 1: the square of a standard normal, so ``Phi^-1((1 - p) / 2) ** 2`` (the lower tail: ``1 - p`` is
    exact for p >= 0.5, ``(1 + p) / 2`` would round away the digits of a p near 1); dof 2: an exponential
    with mean 2, so ``-2 ln(1 - p)``.
    """
    if not 0.0 < probability < 1.0:
        raise EstimatorSetupError("gate_probability", f"must be in (0, 1), got {probability}")
    if dof == 1:
        return NormalDist().inv_cdf(0.5 * (1.0 - probability)) ** 2
    if dof == 2:
        return -2.0 * math.log1p(-probability)
    raise EstimatorSetupError("gate dimension", f"closed-form quantiles exist here for 1 or 2, got {dof}")
