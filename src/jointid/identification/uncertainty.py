"""Uncertainty and identifiability of an identified optimum (:mod:`jointid.identification.identify`).

Uncertainty (linearised at the optimum).  Each measured frequency has relative standard deviation
``sigma_rel / sqrt(w_i)`` (the weights are relative precisions; unit weights mean every frequency
has ``sigma_rel``), extra residuals are taken to carry the same ``sigma_rel``.  With ``J`` the
Jacobian of the weighted relative residuals (``J^T J = J_rel^T W J_rel``)::

    cov(x) = sigma_rel^2 * (J^T J)^+        (coded units, pseudo-inverse)

95 % intervals are ``x +- 1.96 sd`` in coded units, i.e. symmetric in log10 of the parameter and
asymmetric in the physical parameter.  Directions that the data do not determine (zero singular
values of ``J``) get infinite variance rather than the pseudo-inverse's zero, so the parameters
involved get unbounded intervals (``0 .. inf`` physically).

Identifiability (as in ``docs/effects.md``, "Statistics"): SVD of the column-normalised Jacobian; if ``s_min / s_max < 1e-3`` the right singular vector of ``s_min`` names
the combination of parameters that the data cannot resolve.
"""

from __future__ import annotations

import warnings

import numpy as np

from jointid.errors import NumericalWarning

__all__ = ["IDENTIFIABILITY_RATIO", "BOUND_TOL", "Z95", "covariance", "identifiability", "warn_undetermined",
           "physical_values", "bound_flags"]

IDENTIFIABILITY_RATIO = 1e-3  # flag s_min/s_max below this
BOUND_TOL = 1e-3  # coded distance to a bound counted as "on the bound"
Z95 = 1.959963984540054
CONFIG_PREFIX = "joints.parameters"


def covariance(J, k, sigma_rel):
    """Covariance (coded) through the SVD of ``J``; undetermined directions get infinite variance.
    Returns ``(cov (k, k), sd (k,), singular, involved)`` (``involved``: parameters with infinite
    variance, None when ``J^T J`` is regular)."""
    _, sv, Vt = np.linalg.svd(J, full_matrices=True)
    s_full = np.zeros(k)
    s_full[: min(sv.size, k)] = sv[:k]
    V = Vt.T
    tol = max(J.shape) * np.finfo(float).eps * (s_full.max() if s_full.size else 0.0)
    null = s_full <= tol
    cov = sigma_rel**2 * (V[:, ~null] / s_full[~null] ** 2) @ V[:, ~null].T
    var = np.diag(cov).copy()
    cov_singular = bool(np.any(null))
    involved = None
    if cov_singular:
        involved = np.any(np.abs(V[:, null]) > 1e-6, axis=1)
        var[involved] = np.inf
    sd = np.sqrt(var)
    return cov, sd, cov_singular, involved


def identifiability(J, k, names, lo_p, hi_p):
    """SVD of the column-normalised Jacobian.  Returns ``(singular values (k,), s_min/s_max,
    condition number, weakest combination (text), half)`` with ``half`` = d log10(theta)/dx (k,),
    None without physical bounds."""
    norms = np.linalg.norm(J, axis=0)
    Jn = J / np.where(norms > 0, norms, 1.0)
    _, sn, Vnt = np.linalg.svd(Jn, full_matrices=True)
    sn_full = np.zeros(k)
    sn_full[: min(sn.size, k)] = sn[:k]
    ratio = sn_full[-1] / sn_full[0] if sn_full[0] > 0 else 0.0
    condition_number = float(np.inf if ratio == 0 else 1.0 / ratio)
    v_weak = Vnt[-1] / np.where(norms > 0, norms, 1.0)  # back to coded coordinates
    if lo_p is not None:
        half = 0.5 * (np.log10(hi_p) - np.log10(lo_p))  # d log10(theta) / dx
        weakest = _combination(v_weak * half, names, "in log10")
    else:
        half = None
        weakest = _combination(v_weak, names, "in coded units")
    return sn_full, ratio, condition_number, weakest, half


def warn_undetermined(identifiable, cov_singular, weakest, ratio, names, involved) -> None:
    """Warn (at the caller of :func:`jointid.identification.identify.identify`) about an unidentifiable combination or a singular
    ``J^T J``."""
    if not identifiable:
        warnings.warn(
            f"identify: {weakest} is not identifiable from these data (singular value ratio "
            f"{ratio:.1e} < {IDENTIFIABILITY_RATIO:g}); fix one of these parameters, add modes or "
            f"mode shapes, or reparameterise"
            + (f"; J^T J is singular, so the intervals of "
               f"{', '.join(n for n, b in zip(names, involved) if b)} are unbounded"
               if cov_singular else ""),
            NumericalWarning, stacklevel=3)
    elif cov_singular:
        warnings.warn(
            f"identify: J^T J is numerically singular; the intervals of "
            f"{', '.join(n for n, b in zip(names, involved) if b)} are unbounded",
            NumericalWarning, stacklevel=3)


def physical_values(x, sd, half, lo_p, k):
    """``(log10_theta, sd_log10, theta, ci_lower, ci_upper)`` of the coded optimum ``x``: physical
    with log coding (``half`` given), coded (NaN log10 values) without."""
    if half is not None:
        log10_theta = np.log10(lo_p) + (x + 1.0) * half
        sd_log10 = sd * half
        theta = 10.0**log10_theta
        with np.errstate(over="ignore"):
            ci_lower = 10.0 ** (log10_theta - Z95 * sd_log10)
            ci_upper = 10.0 ** (log10_theta + Z95 * sd_log10)
    else:
        log10_theta = np.full(k, np.nan)
        sd_log10 = np.full(k, np.nan)
        theta = x.copy()
        ci_lower = x - Z95 * sd
        ci_upper = x + Z95 * sd
    return log10_theta, sd_log10, theta, ci_lower, ci_upper


def bound_flags(x, names, lo_b, hi_b, half, lo_p) -> list[str]:
    """Parameters within :data:`BOUND_TOL` (coded) of a bound, each with a warning (at the caller of
    :func:`identify`)."""
    on_bound = []
    for i, name in enumerate(names):
        for side, b in (("lower", lo_b[i]), ("upper", hi_b[i])):
            if abs(x[i] - b) <= BOUND_TOL:
                on_bound.append(name)
                if half is not None:
                    bval = _fmt_num(10.0 ** (np.log10(lo_p[i]) + (b + 1.0) * half[i]))
                else:
                    bval = f"{b:g} (coded)"
                warnings.warn(
                    f"{name} sits on its {side} bound {bval}: the surface is extrapolating beyond "
                    f"the DOE (the best fit lies at or past the edge of the parameter range); "
                    f"widen {CONFIG_PREFIX}.{name} bounds",
                    NumericalWarning, stacklevel=3)
                break
    return on_bound


def _combination(v: np.ndarray, names: list[str], unit: str) -> str:
    v = v / np.linalg.norm(v)
    if v[np.argmax(np.abs(v))] < 0:
        v = -v
    order = [i for i in np.argsort(-np.abs(v)) if abs(v[i]) >= 0.05]
    parts = []
    for n_, i in enumerate(order):
        c = v[i]
        if n_ == 0:
            parts.append(f"{c:.2f}*{names[i]}")
        else:
            parts.append(f"{'-' if c < 0 else '+'} {abs(c):.2f}*{names[i]}")
    return " ".join(parts) + f" ({unit})"


def _fmt_num(v: float) -> str:
    s = f"{v:.3g}"
    if "e" in s:
        mant, exp = s.split("e")
        s = f"{mant}e{int(exp)}"
    return s
