"""Multi-output response surfaces over coded joint parameters.

A surface maps coded parameters ``x`` (shape ``(k,)``, see :mod:`jointid.identification.doe`) to ``n_responses``
outputs, typically the natural frequencies of the tracked modes.  Two kinds:

* ``"quadratic"``: full second-order polynomial per response, fitted by least squares, with terms
  in the order ``1, x_0..x_{k-1}, x_i x_j (i < j, row-major), x_0^2..x_{k-1}^2``
  (``(k+1)(k+2)/2`` terms).  Diagnostics: R^2, adjusted R^2, predicted R^2 from PRESS through the
  hat matrix, RMSE.
* ``"rbf"``: ``scipy.interpolate.RBFInterpolator`` with a thin-plate-spline kernel and a degree-1
  polynomial tail; it interpolates the training data exactly, so judge it by predicted R^2
  (leave-one-out) and verification points, not by R^2.

Which response to fit is the caller's choice.  Fitting ``log(freq_Hz)`` rather than ``freq_Hz`` is
recommended: with frequencies roughly ``∝ k^(η/2)`` and log-coded ``k``, ``log f`` is close to linear
in ``x`` and a quadratic fits it much better.  The identification then needs the frequencies back::

    s = fit_surface(X, np.log(F))
    model = lambda x: np.exp(s(x))                            # (m,) in Hz
    jac = lambda x: np.exp(s(x))[:, None] * s.jacobian(x)     # (m, k) in Hz per coded unit

Always check a surface at fresh points solved by the FE model (:func:`verification_errors`,
points from :func:`jointid.identification.doe.verification_points`); accept it only when the error is < 1 %.
"""

from __future__ import annotations

import itertools
import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.interpolate import RBFInterpolator

from jointid.identification.doe import n_quadratic_terms
from jointid.errors import ConfigError, NumericalWarning

__all__ = [
    "Surface",
    "QuadraticSurface",
    "RBFSurface",
    "fit_surface",
    "quadratic_basis",
    "diagnostics",
    "verification_errors",
]

SURFACE_KINDS = ("quadratic", "rbf")
_RBF_KERNEL = "thin_plate_spline"
_RBF_DEGREE = 1
_FD_STEP = 1e-6  # coded units, central differences for the RBF Jacobian


def _as_points(X, k: int | None = None) -> np.ndarray:
    X = np.asarray(X, dtype=float)
    if X.ndim == 1:
        X = X[None, :]
    if X.ndim != 2:
        raise ConfigError(f"surface: points must be shaped (n_points, k), got shape {X.shape}")
    if k is not None and X.shape[1] != k:
        raise ConfigError(f"surface: points have {X.shape[1]} coordinates but the surface has "
                          f"{k} factors; pass one coded value per joint parameter")
    return X


def _pairs(k: int) -> list[tuple[int, int]]:
    return list(itertools.combinations(range(k), 2))


def quadratic_basis(X) -> np.ndarray:
    """Design matrix of the full quadratic.

    Parameters
    ----------
    X : array_like, shape (n, k)
        Coded points.

    Returns
    -------
    numpy.ndarray, shape (n, (k+1)(k+2)/2)
        Columns ``1, x_i, x_i x_j (i<j), x_i^2``.
    """
    X = _as_points(X)
    n, k = X.shape
    cols = [np.ones(n)] + [X[:, i] for i in range(k)]
    cols += [X[:, i] * X[:, j] for i, j in _pairs(k)]
    cols += [X[:, i] ** 2 for i in range(k)]
    return np.column_stack(cols)


def _quadratic_basis_gradient(x: np.ndarray) -> np.ndarray:
    """d(basis)/dx at one point: shape (n_terms, k)."""
    k = x.size
    G = np.zeros((n_quadratic_terms(k), k))
    for i in range(k):
        G[1 + i, i] = 1.0
    for t, (i, j) in enumerate(_pairs(k)):
        G[1 + k + t, i] = x[j]
        G[1 + k + t, j] = x[i]
    off = 1 + k + len(_pairs(k))
    for i in range(k):
        G[off + i, i] = 2.0 * x[i]
    return G


@dataclass
class Surface:
    """Base class of fitted response surfaces (use :func:`fit_surface`).

    Attributes
    ----------
    n_factors : int
        Number of coded inputs ``k``.
    response_names : list of str
        One name per output (default ``"y0", "y1", ...``).
    """

    n_factors: int
    response_names: list[str]

    kind = "base"

    @property
    def n_responses(self) -> int:
        return len(self.response_names)

    @property
    def n_terms(self) -> int:  # pragma: no cover - overridden
        raise NotImplementedError

    def predict(self, X) -> np.ndarray:
        """Evaluate at points ``X`` of shape (n, k) (or (k,) for one point); returns (n, n_responses)."""
        raise NotImplementedError  # pragma: no cover

    def jacobian(self, x) -> np.ndarray:
        """d(response)/d(x) at one point ``x`` (k,); returns (n_responses, k) per coded unit."""
        raise NotImplementedError  # pragma: no cover

    def __call__(self, x) -> np.ndarray:
        """Evaluate at one point ``x`` (k,); returns (n_responses,) (the identification model form)."""
        return self.predict(np.asarray(x, dtype=float).reshape(1, -1))[0]

    def to_dict(self) -> dict:
        """JSON-serialisable description (plain lists and floats)."""
        raise NotImplementedError  # pragma: no cover

    @staticmethod
    def from_dict(d: dict) -> "Surface":
        """Rebuild a surface written by :meth:`to_dict`."""
        kind = d.get("kind")
        if kind == "quadratic":
            return QuadraticSurface(
                n_factors=int(d["n_factors"]),
                response_names=[str(s) for s in d["response_names"]],
                coef=np.asarray(d["coef"], dtype=float).reshape(-1, len(d["response_names"])),
            )
        if kind == "rbf":
            return RBFSurface(
                n_factors=int(d["n_factors"]),
                response_names=[str(s) for s in d["response_names"]],
                X_train=np.asarray(d["X_train"], dtype=float).reshape(-1, int(d["n_factors"])),
                Y_train=np.asarray(d["Y_train"], dtype=float).reshape(-1, len(d["response_names"])),
            )
        raise ConfigError(f"surface: unknown kind {kind!r} in stored surface; expected one of "
                          f"{', '.join(SURFACE_KINDS)} (was the file written by jointid?)")


@dataclass
class QuadraticSurface(Surface):
    """Full quadratic per response; ``coef`` has shape (n_terms, n_responses)."""

    coef: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    kind = "quadratic"

    @property
    def n_terms(self) -> int:
        return n_quadratic_terms(self.n_factors)

    def predict(self, X) -> np.ndarray:
        return quadratic_basis(_as_points(X, self.n_factors)) @ self.coef

    def jacobian(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float).reshape(-1)
        _as_points(x, self.n_factors)
        return (_quadratic_basis_gradient(x).T @ self.coef).T

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "n_factors": int(self.n_factors),
            "response_names": list(self.response_names),
            "terms": _term_names(self.n_factors),
            "coef": np.asarray(self.coef, dtype=float).tolist(),
        }


@dataclass
class RBFSurface(Surface):
    """Thin-plate-spline interpolant (degree-1 tail) of the training data."""

    X_train: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    Y_train: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    kind = "rbf"

    def __post_init__(self):
        self._interp = _rbf(self.X_train, self.Y_train)

    @property
    def n_terms(self) -> int:
        # An interpolant has as many free coefficients as data (n weights + k+1 tail coefficients
        # tied by k+1 orthogonality conditions).
        return int(self.X_train.shape[0])

    def predict(self, X) -> np.ndarray:
        return self._interp(_as_points(X, self.n_factors))

    def jacobian(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float).reshape(-1)
        _as_points(x, self.n_factors)
        k = x.size
        P = np.vstack([x + _FD_STEP * e for e in np.eye(k)] + [x - _FD_STEP * e for e in np.eye(k)])
        V = self.predict(P)
        return ((V[:k] - V[k:]) / (2.0 * _FD_STEP)).T

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "n_factors": int(self.n_factors),
            "response_names": list(self.response_names),
            "kernel": _RBF_KERNEL,
            "degree": _RBF_DEGREE,
            "X_train": self.X_train.tolist(),
            "Y_train": self.Y_train.tolist(),
        }


def _term_names(k: int) -> list[str]:
    return (["1"] + [f"x{i}" for i in range(k)] + [f"x{i}*x{j}" for i, j in _pairs(k)]
            + [f"x{i}^2" for i in range(k)])


def _rbf(X: np.ndarray, Y: np.ndarray) -> RBFInterpolator:
    return RBFInterpolator(X, Y, kernel=_RBF_KERNEL, degree=_RBF_DEGREE, smoothing=0.0)


def _check_data(X, Y) -> tuple[np.ndarray, np.ndarray]:
    X = _as_points(X)
    Y = np.asarray(Y, dtype=float)
    if Y.ndim == 1:
        Y = Y[:, None]
    problems = []
    if Y.ndim != 2 or Y.shape[0] != X.shape[0]:
        problems.append(f"surface: X has {X.shape[0]} points but Y has shape {Y.shape}; give one "
                        f"row of responses per design point")
    if not np.all(np.isfinite(X)):
        problems.append("surface: X contains NaN/inf; every design point needs finite coded values")
    if Y.ndim == 2 and not np.all(np.isfinite(Y)):
        bad = sorted(set(np.nonzero(~np.isfinite(Y))[0].tolist()))
        problems.append(f"surface: responses at design rows {bad} are NaN/inf; re-run or drop the "
                        f"failed FE solves before fitting")
    if problems:
        raise ConfigError(problems)
    return X, Y


def fit_surface(X, Y, kind: str = "quadratic", *, response_names=None) -> Surface:
    """Fit a multi-output response surface.

    Parameters
    ----------
    X : array_like, shape (n_points, k)
        Coded design points.
    Y : array_like, shape (n_points, n_responses) or (n_points,)
        Responses (e.g. ``freq_Hz`` or, better, ``log(freq_Hz)``; see module docstring).
    kind : {"quadratic", "rbf"}
        Surface type.
    response_names : sequence of str, optional
        Names of the responses (default ``"y0", "y1", ...``).

    Returns
    -------
    Surface
        :class:`QuadraticSurface` or :class:`RBFSurface`.

    Raises
    ------
    ConfigError
        Unknown kind, mismatched shapes, non-finite data, too few points for a quadratic.

    Warns
    -----
    NumericalWarning
        The quadratic design matrix is rank deficient (coefficients are then minimum-norm).
    """
    X, Y = _check_data(X, Y)
    n, k = X.shape
    names = ([f"y{i}" for i in range(Y.shape[1])] if response_names is None
             else [str(s) for s in response_names])
    if len(names) != Y.shape[1]:
        raise ConfigError(f"surface: {len(names)} response names for {Y.shape[1]} responses; "
                          f"give one name per column of Y")
    if kind == "quadratic":
        p = n_quadratic_terms(k)
        if n < p:
            raise ConfigError(
                f"surface: {n} points but a full quadratic in {k} factors needs {p}; use ccf or "
                f"raise doe.n_samples to >= {2 * p}"
            )
        A = quadratic_basis(X)
        coef, _, rank, _ = np.linalg.lstsq(A, Y, rcond=None)
        if rank < p:
            warnings.warn(
                f"surface: the quadratic design matrix has rank {rank} < {p} terms; the design "
                f"does not separate all quadratic terms (use ccf or more points)",
                NumericalWarning, stacklevel=2)
        return QuadraticSurface(n_factors=k, response_names=names, coef=coef)
    if kind == "rbf":
        if n < k + 1:
            raise ConfigError(f"surface: rbf needs at least {k + 1} points for {k} factors, got "
                              f"{n}; use a larger design")
        return RBFSurface(n_factors=k, response_names=names, X_train=X.copy(), Y_train=Y.copy())
    raise ConfigError(f"surface.kind: unknown surface {kind!r}; use one of "
                      f"{', '.join(SURFACE_KINDS)}")


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
    X, Y = _check_data(X, Y)
    X = _as_points(X, surface.n_factors)
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
                loo[i] = _rbf(X[keep], Y[keep])(X[i:i + 1])[0]
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
    X, Y = _check_data(X, Y)
    E = surface.predict(_as_points(X, surface.n_factors)) - Y
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
