"""Information criteria of the diagnosis, on numbers alone: the chi-square p-value and AICc.

A variant "explains" the data when its chi-square is consistent with the noise (p >= ``alpha``);
``AICc = chi2 + 2k + 2k(k+1)/(n-k-1)`` ranks variants at the stated noise (the model error's QAICc is
:func:`jointid.identification.model_error.qaicc`).  Kept apart from :mod:`jointid.diagnosis.statistics`
(the score tests, which take a diagnoser) so that the fit results can use them without a cycle.
"""

from __future__ import annotations

import math

from jointid.identification.model_error import qaicc

__all__ = ["aicc", "chi2_p_value", "chi2_sf"]


def chi2_sf(x: float, dof: float) -> float:
    """``scipy.stats.chi2.sf(x, dof)``, the same numbers (``scipy.special.chdtrc``, which it calls),
    without importing ``scipy.stats`` (about 0.6 s, paid by every Snakemake start through the rules'
    imports): NaN for ``dof <= 0``, 1 for ``x < 0``."""
    from scipy.special import chdtrc

    if not dof > 0:
        return math.nan
    if x < 0:
        return 1.0
    return float(chdtrc(dof, x))


def chi2_p_value(chi2: float, dof: int) -> float:
    """Probability of a chi-square at least ``chi2`` with ``dof`` degrees of freedom (noise only)."""
    return chi2_sf(chi2, dof)


def aicc(chi2: float, n: int, k: int) -> float:
    """Corrected Akaike criterion ``chi2 + 2k + 2k(k+1)/(n-k-1)`` (sigma known; inf for n <= k + 1):
    :func:`jointid.identification.model_error.qaicc` of a chi-square at the stated noise.

    Parameters
    ----------
    chi2 : float
        Sum of squared sigma-normalised residuals.
    n, k : int
        Number of residuals and of fitted parameters.
    """
    return qaicc(chi2, n, k)
