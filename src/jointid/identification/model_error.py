"""The likelihood with model error: what a fit above its noise means for every comparison of fits.

A frequency residual ``e_i = ln(f_model / f_meas)`` has the stated measurement uncertainty ``s_i``
(relative, from the dataset), a known part ``k_i`` (the mesh's discretisation error, when estimated)
and a model error ``sigma_m`` common to all modes, which is whatever the model cannot represent:

    e_i ~ N(0, s_i^2 + k_i^2 + sigma_m^2)

The known part may be correlated between rows: the mesh's remaining error belongs to a *mode*, so the
same mode measured in two states carries the same error in both (``known_corr``, a correlation matrix,
:func:`mode_correlation`).  The total covariance is then ``S + D R D + sigma_m^2 I`` with
``S = diag(s_i^2)``, ``D = diag(k_i)``, and every chi-square below is the generalised one,
``e^T C^-1 e``.  A difference between states then carries no mesh error, as it should: a refinement
moves a mode's frequency alike in every state.

``sigma_m`` is estimated once per comparison, from its *reference fit*: the fit of least chi-square
per degree of freedom among the models compared (for nested candidates, the most general; for
non-nested reconstructions, the best).  Without a known part it solves the moment equation of Paule
and Mandel (1982),

    sum_i e_i^2 / (s_i^2 + k_i^2 + sigma_m^2) = n - k,        sigma_m >= 0.

With a known part, the rows' variances differ by orders of magnitude (a mesh error of 2 % beside a
noise of 0.1 %), and the moment equation would let a row dominated by its known part count for a full
degree of freedom while it carries almost no information on ``sigma_m``: an overstated known part then
drives ``sigma_m`` down, and an understated noise goes unseen.  There ``sigma_m`` solves the
likelihood's estimating equation instead, each row weighted by ``w_i = 1 / (s_i^2 + k_i^2 + sigma_m^2)``
and the degrees of freedom spread over the rows (the maximum-likelihood equation of the random-effects
model with the ``(n - k) / n`` correction of restricted likelihood for equal rows; Viechtbauer, J. Educ.
Behav. Stat. 30, 2005),

    sum_i w_i^2 e_i^2 = (n - k) / n  sum_i w_i,

which equals the moment equation when all rows have the same variance.  With correlated known parts
both equations are solved in the eigenbasis of ``S + D R D``, where the rows are independent.

and then held fixed while every model of the comparison is judged.  With one stated uncertainty for
all modes and no known part, this is the variance-inflation factor of quasi-likelihood,
``c_hat = chi2 / dof`` with ``sigma^2 + sigma_m^2 = c_hat sigma^2``, and the criterion below is
Burnham and Anderson's QAICc (*Model Selection and Multimodel Inference*, 2nd ed., 2002, sec. 2.5 and
6.2).  Where the reference fits within its noise (``c_hat <= 1``), ``sigma_m = 0`` and everything is
the plain chi-square and AICc of the stated noise.

QAICc here is ``chi2_m + 2k + 2k(k+1)/(n-k-1)`` with ``chi2_m`` the chi-square at the total
uncertainty.  Burnham and Anderson also count ``c_hat`` as one more parameter of every model; being
common to all models of a comparison it cancels in every difference, except for a small change of
the small-sample term, and is left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

__all__ = ["ModelError", "NO_MODEL_ERROR", "estimate", "from_chi2", "qaicc", "akaike_weights", "support_text",
           "mode_correlation", "known_budget", "cluster_factor", "SUPPORT_STRONG", "SUPPORT_SOME"]

SUPPORT_STRONG = 10.0
"""A model ahead by at least this much QAICc has strong support over the other (Burnham and Anderson,
sec. 2.6: the other has essentially none)."""
SUPPORT_SOME = 4.0
"""Ahead by at least this much: the other has considerably less support (same place)."""


@dataclass(frozen=True)
class ModelError:
    """The model error of one comparison of fits, estimated from its reference fit.

    Attributes
    ----------
    sigma_model_rel : float
        ``sigma_m``, the model error per mode, relative (0.04 = 4 % of the frequency).
    sigma_noise_rel : float
        The stated measurement uncertainty (root mean square over the reference's residual rows).
    c_hat : float
        Lack of fit of the reference at the stated noise, ``chi2 / dof`` (>= 0; not floored).
    reference : str
        Which fit the estimate comes from.
    chi2, dof : float, int
        The reference's chi-square at the stated noise and its degrees of freedom.
    sigma_known_rel : float
        Root mean square of the known part (the mesh error) over the reference's rows.
    shape : ModelError or None
        The model error of the mode-shape rows, a block of its own (same fields; the uncertainties are
        fractions of each measured mode's RMS displacement).  None: no shape rows.  Each block gets its
        own ``sigma_m`` so that many well-fitting shape rows cannot hide an understated frequency
        noise (docs/effects.md, "Shapes in the fit").
    design_effect : float
        Rows that are not independent (a shape's model error moves all of the mode's displacements
        together) carry less evidence than their number says: every total variance is multiplied by
        this factor (>= 1), which divides their chi-square as Rao and Scott's first-order correction
        does (J. Amer. Statist. Assoc. 76, 1981).  1 for independent rows.
    """

    sigma_model_rel: float = 0.0
    sigma_noise_rel: float = 0.0
    c_hat: float = 1.0
    reference: str = ""
    chi2: float = 0.0
    dof: int = 1
    sigma_known_rel: float = 0.0
    shape: "ModelError | None" = None
    design_effect: float = 1.0

    @property
    def inflation(self) -> float:
        """``(s^2 + k^2 + sigma_m^2) / s^2`` at the root-mean-square noise: the factor a chi-square at the
        stated noise is divided by (``max(1, c_hat)`` without a known part)."""
        s2 = self.sigma_noise_rel ** 2
        total = (s2 + self.sigma_known_rel ** 2 + self.sigma_model_rel ** 2) * self.design_effect
        return total / s2 if s2 > 0 else 1.0

    @property
    def above_noise(self) -> bool:
        """Whether the reference fits worse than its noise (a model error is estimated)."""
        return self.sigma_model_rel > 0.0

    def variances(self, sigma_rel, known_rel=None) -> np.ndarray:
        """Total variance per residual row: ``(s_i^2 + k_i^2 + sigma_m^2)`` times :attr:`design_effect`."""
        s = np.asarray(sigma_rel, float)
        k = np.zeros_like(s) if known_rel is None else np.asarray(known_rel, float)
        return (s ** 2 + k ** 2 + self.sigma_model_rel ** 2) * self.design_effect

    def covariance(self, sigma_rel, known_rel=None, known_corr=None) -> np.ndarray:
        """Total covariance of the rows ``(S + D R D + sigma_m^2 I)`` times :attr:`design_effect` (module
        doc); ``known_corr`` None: the known parts are independent (``R = I``)."""
        s = np.asarray(sigma_rel, float)
        k = np.zeros_like(s) if known_rel is None else np.asarray(known_rel, float)
        R = np.eye(len(s)) if known_corr is None else np.asarray(known_corr, float)
        C = np.diag(s ** 2 + self.sigma_model_rel ** 2) + k[:, None] * R * k[None, :]
        return C * self.design_effect

    def chi2_total(self, r, sigma_rel, known_rel=None, known_corr=None) -> float:
        """Chi-square at the total uncertainty of sigma-normalised residuals ``r`` (``r_i = e_i / s_i``);
        with ``known_corr``, the generalised ``e^T C^-1 e`` (:meth:`covariance`)."""
        r = np.asarray(r, float)
        s = np.broadcast_to(np.asarray(sigma_rel, float), r.shape)
        e = r * s
        k = None if known_rel is None else np.broadcast_to(known_rel, r.shape)
        if known_corr is None or not len(r):
            return float(np.sum(e ** 2 / self.variances(s, k)))
        return float(e @ np.linalg.solve(self.covariance(s, k, known_corr), e))

    def whitener(self, sigma_rel, known_rel=None, known_corr=None) -> np.ndarray:
        """The matrix ``A`` that takes sigma-normalised rows (residuals ``r`` or Jacobian rows) to units
        of the total uncertainty, ``A r = C^-1/2 e``: ``(A r)^T (A r)`` is :meth:`chi2_total` and
        ``(A J)^T (A J)`` the information of the parameters.  Without ``known_corr`` it is diagonal,
        ``diag(sqrt(row_weights))``."""
        s = np.asarray(sigma_rel, float)
        if known_corr is None:
            return np.diag(np.sqrt(self.row_weights(s, known_rel)))
        lam, Q = np.linalg.eigh(self.covariance(s, known_rel, known_corr))
        return (Q / np.sqrt(np.maximum(lam, 1e-300))) @ Q.T * s[None, :]

    def row_weights(self, sigma_rel, known_rel=None) -> np.ndarray:
        """Per row ``s_i^2 / (s_i^2 + k_i^2 + sigma_m^2)``: what a chi-square contribution at the stated
        noise is multiplied by to count at the total uncertainty."""
        s = np.asarray(sigma_rel, float)
        return s ** 2 / self.variances(s, known_rel)

    def record(self) -> dict:
        """JSON-ready summary (percentages, as reported); the shape block's under ``shape_*`` keys."""
        out = {"sigma_model_pct": 100 * self.sigma_model_rel, "sigma_noise_pct": 100 * self.sigma_noise_rel,
               "sigma_known_pct": 100 * self.sigma_known_rel, "c_hat": self.c_hat,
               "inflation": self.inflation, "reference": self.reference, "reference_chi2": self.chi2,
               "reference_dof": int(self.dof)}
        if self.shape is not None:
            out.update({"shape_sigma_model_pct": 100 * self.shape.sigma_model_rel,
                        "shape_sigma_noise_pct": 100 * self.shape.sigma_noise_rel,
                        "shape_sigma_known_pct": 100 * self.shape.sigma_known_rel,
                        "shape_c_hat": self.shape.c_hat, "shape_reference_dof": int(self.shape.dof),
                        "shape_design_effect": self.shape.design_effect})
        return out

    def sentence(self) -> str:
        """The headline: the model's remaining error per mode against the noise (and the shapes')."""
        noise = 100 * self.sigma_noise_rel
        known = (f", beside a known error of {100 * self.sigma_known_rel:.2g} % (the mesh)"
                 if self.sigma_known_rel > 0 else "")
        if not self.above_noise:
            txt = (f"The best model fits within the stated noise of {noise:.2g} % per mode{known} "
                   f"(chi2/dof = {self.c_hat:.2f}); no model error is estimated.")
        else:
            txt = (f"The model's remaining error is about {100 * self.sigma_model_rel:.2g} % per mode, "
                   f"{self.sigma_model_rel / self.sigma_noise_rel:.1f} times the stated measurement noise of "
                   f"{noise:.2g} %{known} (chi2/dof = {self.c_hat:.1f} for {self.reference}; either the model "
                   f"misses something or the noise is understated by a factor of about "
                   f"{math.sqrt(self.c_hat):.1f}).")
        return txt + (" " + self.shape.shape_sentence() if self.shape is not None else "")

    def shape_sentence(self) -> str:
        """The shape block's model error in one sentence (this object being the shape block)."""
        noise = 100 * self.sigma_noise_rel
        if not self.above_noise:
            return (f"The mode shapes fit within their noise of {noise:.2g} % of each mode's RMS "
                    f"(chi2/dof = {self.c_hat:.2f}).")
        corr = (f"; their rows move together within a mode, so they count {self.design_effect:.1f} times less"
                if self.design_effect > 1.0 else "")
        return (f"The mode shapes carry a model error of about {100 * self.sigma_model_rel:.2g} % of each mode's "
                f"RMS beside their noise of {noise:.2g} % (chi2/dof = {self.c_hat:.1f}{corr}).")


NO_MODEL_ERROR = ModelError()
"""The exact-model likelihood (no model error): plain chi-square and AICc."""


def mode_correlation(shapes) -> np.ndarray:
    """The correlation of rows whose errors belong to modes: ``MAC(phi_i, phi_j)`` of the rows' model
    shapes ``shapes`` (n_dofs, n_rows); a column of zeros or NaN (a row without a mode) is correlated
    with nothing.  The MAC matrix is positive semi-definite (the Hadamard square of the normalised Gram
    matrix, Schur's product theorem) and has a unit diagonal, so it is a correlation matrix."""
    P = np.nan_to_num(np.asarray(shapes, float))
    norm = np.sqrt((P * P).sum(axis=0))
    ok = norm > 0
    G = np.zeros((P.shape[1], P.shape[1]))
    Pn = P[:, ok] / norm[ok]
    G[np.ix_(ok, ok)] = Pn.T @ Pn
    R = G ** 2
    np.fill_diagonal(R, 1.0)
    return R


def cluster_factor(cov: np.ndarray, Jw: np.ndarray, rw: np.ndarray, groups, n_params: int) -> float:
    """How much wider the cluster-robust (sandwich) variances are than ``cov``, at least 1: ``cov M cov``
    with ``M = G/(G - p) sum_g u_g u_g^T``, ``u_g = Jw_g^T rw_g`` over the clusters ``groups`` (lists of row
    numbers of the whitened Jacobian ``Jw`` and residuals ``rw``; Liang and Zeger 1986); the largest ratio
    over the parameters.  1 when there are no more clusters than parameters."""
    groups = list(groups)
    G = len(groups)
    if G <= n_params:
        return 1.0
    U = np.array([Jw[g].T @ rw[g] for g in groups])
    robust = cov @ (U.T @ U * G / (G - n_params)) @ cov
    d = np.diag(cov)
    ok = d > 0
    return float(max(1.0, np.max(np.diag(robust)[ok] / d[ok]))) if ok.any() else 1.0


def known_budget(shared, corr, own) -> tuple[np.ndarray, np.ndarray | None]:
    """``(k, R)`` of a known part made of a ``shared`` part per row, correlated by ``corr``, and an ``own``
    part per row, independent of every other row: ``D R D = diag(shared) corr diag(shared) + diag(own^2)``,
    ``k = sqrt(shared^2 + own^2)``.  ``R`` is again a correlation matrix (unit diagonal, positive
    semi-definite as a sum of two such covariances).  ``R`` is None where no row has a known part."""
    shared, own = np.asarray(shared, float), np.asarray(own, float)
    k = np.sqrt(shared ** 2 + own ** 2)
    if not k.any():
        return k, None
    C = shared[:, None] * np.asarray(corr, float) * shared[None, :] + np.diag(own ** 2)
    safe = np.where(k > 0, k, 1.0)
    R = C / np.outer(safe, safe)
    np.fill_diagonal(R, 1.0)
    return k, R


def estimate(r, sigma_rel, n_params: int, *, known_rel=None, known_corr=None, reference: str = "") -> ModelError:
    """The model error of a reference fit with sigma-normalised residuals ``r`` and ``n_params`` fitted
    parameters (the Paule-Mandel moment equation of the module doc).

    Parameters
    ----------
    r : (n,) array
        Residuals in units of their stated uncertainty, ``ln(f_model / f_meas) / s_i``.
    sigma_rel : float or (n,) array
        Stated relative uncertainty ``s_i`` per row.
    n_params : int
        Parameters fitted (the degrees of freedom are ``max(n - n_params, 1)``).
    known_rel : (n,) array, optional
        A known part of the model error per row (relative), e.g. the mesh's discretisation error.
    known_corr : (n, n) array, optional
        The known parts' correlation between rows (:func:`mode_correlation`); None: independent.  The
        moment equation is then solved in the eigenbasis of ``S + D R D``, where it is a sum again.
    """
    r = np.asarray(r, float)
    s = np.broadcast_to(np.asarray(sigma_rel, float), r.shape).astype(float)
    k = np.zeros_like(s) if known_rel is None else np.broadcast_to(np.asarray(known_rel, float), r.shape)
    e2 = (r * s) ** 2
    dof = max(len(r) - int(n_params), 1)
    chi2 = float(np.sum(r ** 2))
    noise = float(np.sqrt(np.mean(s ** 2))) if len(s) else 0.0
    known = float(np.sqrt(np.mean(k ** 2))) if len(k) else 0.0
    base = s ** 2 + k ** 2
    if known_corr is not None and len(r) and k.any():  # the same sum in the eigenbasis of S + D R D
        lam, Q = np.linalg.eigh(np.diag(s ** 2) + k[:, None] * np.asarray(known_corr, float) * k[None, :])
        e2, base = (Q.T @ (r * s)) ** 2, np.maximum(lam, 0.0)

    if k.any():  # the weighted (likelihood) equation: rows dominated by the known part carry little weight
        def excess(var_m: float) -> float:
            w = 1.0 / (base + var_m)
            return float(np.sum(e2 * w * w)) - dof / len(r) * float(np.sum(w))
    else:
        def excess(var_m: float) -> float:
            return float(np.sum(e2 / (base + var_m))) - dof

    var_m = 0.0
    if len(r) and not k.any() and np.all(s == s[0]) and chi2 > dof:
        var_m = float(s[0]) ** 2 * (chi2 / dof - 1.0)  # one noise, no known part: the closed form
    elif len(r) and excess(0.0) > 0:
        hi = max(float(np.max(e2)) * len(r), 1e-30)
        while excess(hi) > 0:
            hi *= 4
        var_m = brentq(excess, 0.0, hi, xtol=1e-16, rtol=1e-12)
    return ModelError(sigma_model_rel=math.sqrt(var_m), sigma_noise_rel=noise, c_hat=chi2 / dof,
                      reference=reference, chi2=chi2, dof=dof, sigma_known_rel=known)


def from_chi2(chi2: float, dof: int, sigma_rel: float, *, reference: str = "") -> ModelError:
    """The model error of a fit with one stated uncertainty ``sigma_rel`` for all rows: ``c_hat = chi2 / dof``
    and ``sigma_m = sigma sqrt(max(c_hat - 1, 0))`` (:func:`estimate` with one sigma and no known part)."""
    dof = max(int(dof), 1)
    c_hat = float(chi2) / dof
    return ModelError(sigma_model_rel=float(sigma_rel) * math.sqrt(max(c_hat - 1.0, 0.0)),
                      sigma_noise_rel=float(sigma_rel), c_hat=c_hat, reference=reference, chi2=float(chi2), dof=dof)


def qaicc(chi2_total: float, n: int, k: int) -> float:
    """QAICc ``chi2_total + 2k + 2k(k+1)/(n-k-1)`` of a chi-square at the total uncertainty (inf for
    ``n <= k + 1``); equal to AICc when there is no model error."""
    corr = 2 * k * (k + 1) / (n - k - 1) if n - k - 1 > 0 else math.inf
    return chi2_total + 2 * k + corr


def akaike_weights(values) -> np.ndarray:
    """Akaike weights ``exp(-delta/2) / sum`` of criterion values (QAICc or AICc); non-finite ones get 0."""
    v = np.asarray(values, float)
    ok = np.isfinite(v)
    w = np.zeros(len(v))
    if ok.any():
        w[ok] = np.exp(-0.5 * (v[ok] - v[ok].min()))
        w /= w.sum()
    return w


def support_text(delta: float) -> str:
    """How strongly a model ahead of another by ``-delta`` QAICc is supported: ``strongly``,
    ``moderately`` or ``not`` (thresholds :data:`SUPPORT_STRONG`, :data:`SUPPORT_SOME`)."""
    if not np.isfinite(delta):
        return "not"
    if -delta >= SUPPORT_STRONG:
        return "strongly"
    return "moderately" if -delta >= SUPPORT_SOME else "not"
