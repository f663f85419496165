"""Multi-output response surfaces over coded joint parameters.

A surface maps coded parameters ``x`` (shape ``(k,)``, see :mod:`jointid.identification.doe`) to ``n_responses``
outputs, typically the natural frequencies of the tracked modes.  Two kinds:

* ``"quadratic"``: full second-order polynomial per response, fitted by least squares, with terms
  in the order ``1, x_0..x_{k-1}, x_i x_j (i < j, row-major), x_0^2..x_{k-1}^2``
  (``(k+1)(k+2)/2`` terms).  Diagnostics (:mod:`jointid.identification.surface_checks`): R^2,
  adjusted R^2, predicted R^2 from PRESS through the hat matrix, RMSE.
* ``"rbf"``: ``scipy.interpolate.RBFInterpolator`` with a thin-plate-spline kernel and a degree-1
  polynomial tail; it interpolates the training data exactly, so judge it by predicted R^2
  (leave-one-out) and verification points, not by R^2.

Which response to fit is the caller's choice.  Fitting ``log(freq_Hz)`` rather than ``freq_Hz`` is
recommended: with frequencies roughly ``∝ k^(η/2)`` and log-coded ``k``, ``log f`` is close to linear
in ``x`` and a quadratic fits it much better.  The identification then needs the frequencies back::

    s = fit_surface(X, np.log(F))
    model = lambda x: np.exp(s(x))                            # (m,) in Hz
    jac = lambda x: np.exp(s(x))[:, None] * s.jacobian(x)     # (m, k) in Hz per coded unit

Always check a surface at fresh points solved by the FE model
(:func:`jointid.identification.surface_checks.verification_errors`,
points from :func:`jointid.identification.doe.verification_points`); accept it only when the error is < 1 %.
"""

from __future__ import annotations

import functools
import itertools
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import RBFInterpolator

from jointid.identification.doe import n_quadratic_terms
from jointid.errors import ConfigError, NumericalWarning

__all__ = [
    "Surface",
    "QuadraticSurface",
    "RBFSurface",
    "fit_surface",
    "quadratic_basis",
    "as_points",
    "check_data",
    "rbf_interpolator",
]

SURFACE_KINDS = ("quadratic", "rbf")
_RBF_KERNEL = "thin_plate_spline"
_RBF_DEGREE = 1
_FD_STEP = 1e-6  # coded units, central differences for the RBF Jacobian


def as_points(X, k: int | None = None) -> np.ndarray:
    """``X`` as a float array of shape ``(n_points, k)`` (one point may be 1-D); checks ``k``."""
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
    X = as_points(X)
    n, k = X.shape
    i, j = _pair_columns(k)
    B = np.empty((n, n_quadratic_terms(k)))
    B[:, 0] = 1.0
    B[:, 1:1 + k] = X
    B[:, 1 + k:1 + k + i.size] = X[:, i] * X[:, j]
    B[:, 1 + k + i.size:] = X ** 2
    return B


@functools.lru_cache(maxsize=None)
def _pair_columns(k: int) -> tuple[np.ndarray, np.ndarray]:
    """The columns ``(i, j)``, ``i < j``, of the quadratic's cross terms, in :func:`_pairs` order."""
    pairs = np.array(_pairs(k), dtype=int).reshape(-1, 2)
    return pairs[:, 0].copy(), pairs[:, 1].copy()


def _quadratic_basis_gradient(x: np.ndarray) -> np.ndarray:
    """d(basis)/dx at one point: shape (n_terms, k)."""
    k = x.size
    i, j = _pair_columns(k)
    G = np.zeros((n_quadratic_terms(k), k))
    diag = np.arange(k)
    G[1 + diag, diag] = 1.0
    t = 1 + k + np.arange(i.size)
    G[t, i] = x[j]
    G[t, j] = x[i]
    G[1 + k + i.size + diag, diag] = 2.0 * x
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
        return quadratic_basis(as_points(X, self.n_factors)) @ self.coef

    def jacobian(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float).reshape(-1)
        as_points(x, self.n_factors)
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
        self._interp = rbf_interpolator(self.X_train, self.Y_train)

    @property
    def n_terms(self) -> int:
        # An interpolant has as many free coefficients as data (n weights + k+1 tail coefficients
        # tied by k+1 orthogonality conditions).
        return int(self.X_train.shape[0])

    def predict(self, X) -> np.ndarray:
        return self._interp(as_points(X, self.n_factors))

    def jacobian(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float).reshape(-1)
        as_points(x, self.n_factors)
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


def rbf_interpolator(X: np.ndarray, Y: np.ndarray) -> RBFInterpolator:
    """The interpolator of an rbf surface through ``(X, Y)`` (thin-plate spline, degree-1 tail)."""
    return RBFInterpolator(X, Y, kernel=_RBF_KERNEL, degree=_RBF_DEGREE, smoothing=0.0)


def check_data(X, Y) -> tuple[np.ndarray, np.ndarray]:
    """Coded points ``X`` (n, k) and responses ``Y`` (n, n_responses) as float arrays; raise one
    :class:`ConfigError` listing shape and non-finite problems."""
    X = as_points(X)
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
    X, Y = check_data(X, Y)
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
