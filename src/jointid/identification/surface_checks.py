"""Goodness of fit of a response surface (:mod:`jointid.identification.surface`).

:func:`diagnostics` judges a surface on its training data (R^2, adjusted R^2, predicted R^2 from
PRESS, RMSE); :func:`verification_errors` compares it with reference responses at fresh points
(e.g. FE solves at :func:`jointid.identification.doe.verification_points`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from jointid.errors import ConfigError
from jointid.identification.surface import (QuadraticSurface, RBFSurface, Surface, as_points, check_data,
                                            quadratic_basis, rbf_interpolator)

__all__ = ["diagnostics", "verification_errors"]


def _r2(sse: np.ndarray, sst: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(sst > 0, 1.0 - sse / np.where(sst > 0, sst, 1.0), np.nan)


def diagnostics(surface: Surface, X, Y) -> pd.DataFrame:
    """Goodness-of-fit table of a surface on its *training* data.

    Parameters
    ----------
    surface : Surface
        Surface fitted on ``(X, Y)``.
    X : array_like, shape (n_points, k)
        The coded training points.
    Y : array_like, shape (n_points, n_responses)
        The training responses.

    Returns
    -------
    pandas.DataFrame
        Index ``response`` (the response names); columns

        * ``r2``: ``1 - SSE/SST``;
        * ``r2_adj``: ``1 - (1 - r2)(n - 1)/(n - p)``, NaN when ``n <= p`` (saturated fit);
        * ``r2_pred``: ``1 - PRESS/SST``; quadratic: PRESS from the hat-matrix leverages
          ``sum((e_i / (1 - h_ii))^2)``, NaN where a leverage is 1 (saturated design); rbf:
          leave-one-out refits;
        * ``rmse``: ``sqrt(SSE / n)`` in response units;
        * ``n_points``, ``n_terms`` (``p``; for rbf ``p = n``).

        R^2 values are NaN for a constant response (``SST = 0``).
    """
    X, Y = check_data(X, Y)
    X = as_points(X, surface.n_factors)
    if Y.shape[1] != surface.n_responses:
        raise ConfigError(f"surface: Y has {Y.shape[1]} responses but the surface has "
                          f"{surface.n_responses}; pass the surface's own training data")
    n = X.shape[0]
    p = surface.n_terms
    E = Y - surface.predict(X)
    sse = np.sum(E**2, axis=0)
    sst = np.sum((Y - Y.mean(axis=0)) ** 2, axis=0)
    r2 = _r2(sse, sst)
    r2_adj = (1.0 - (1.0 - r2) * (n - 1) / (n - p)) if n > p else np.full_like(r2, np.nan)

    if isinstance(surface, QuadraticSurface):
        A = quadratic_basis(X)
        h = np.einsum("ij,ji->i", A, np.linalg.pinv(A))  # leverages diag(A A^+)
        tol = 1e-10
        if np.any(h > 1.0 - tol):
            press = np.full(Y.shape[1], np.nan)
        else:
            press = np.sum((E / (1.0 - h)[:, None]) ** 2, axis=0)
    elif isinstance(surface, RBFSurface):
        if n <= surface.n_factors + 1:
            press = np.full(Y.shape[1], np.nan)
        else:
            loo = np.empty_like(Y)
            for i in range(n):
                keep = np.arange(n) != i
                loo[i] = rbf_interpolator(X[keep], Y[keep])(X[i:i + 1])[0]
            press = np.sum((Y - loo) ** 2, axis=0)
    else:  # pragma: no cover
        raise ConfigError(f"surface: diagnostics not available for kind {surface.kind!r}")
    r2_pred = _r2(press, sst)

    return pd.DataFrame(
        {
            "r2": r2,
            "r2_adj": r2_adj,
            "r2_pred": r2_pred,
            "rmse": np.sqrt(sse / n),
            "n_points": n,
            "n_terms": p,
        },
        index=pd.Index(surface.response_names, name="response"),
    )


def verification_errors(surface: Surface, X, Y) -> pd.DataFrame:
    """Surface-vs-reference errors at fresh points (e.g. FE solves at verification points).

    Parameters
    ----------
    surface : Surface
        Fitted surface.
    X : array_like, shape (n, k)
        Coded verification points (not used in the fit).
    Y : array_like, shape (n, n_responses)
        Reference responses at ``X`` in the surface's own response units (if the surface was fitted
        on ``log(freq_Hz)``, pass ``log(freq_Hz)``: the error of a log is the relative error).

    Returns
    -------
    pandas.DataFrame
        Index ``response``; columns ``max_abs_err``, ``rms_err`` (response units),
        ``max_rel_err_pct`` (``100 * max |pred - ref| / |ref|``), ``n_points``.
    """
    X, Y = check_data(X, Y)
    E = surface.predict(as_points(X, surface.n_factors)) - Y
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(E) / np.abs(Y)
    return pd.DataFrame(
        {
            "max_abs_err": np.max(np.abs(E), axis=0),
            "rms_err": np.sqrt(np.mean(E**2, axis=0)),
            "max_rel_err_pct": 100.0 * np.max(rel, axis=0),
            "n_points": X.shape[0],
        },
        index=pd.Index(surface.response_names, name="response"),
    )
