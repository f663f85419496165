"""Parameter identification: fit coded joint parameters to measured natural frequencies.

Generic over the model: ``model(x_coded) -> freq_Hz`` with ``x_coded`` of shape ``(k,)`` and the
result of shape ``(m,)`` (usually a fitted :class:`jointid.identification.surface.Surface`, or the FE model itself).

Objective::

    r_i(x) = sqrt(w_i) * (f_i(x) - f_meas_i) / f_meas_i,     J(x) = sum_i r_i^2  (+ sum extra(x)^2)

minimised by bounded multi-start ``scipy.optimize.least_squares`` (starts: the centre of the box and
a seeded Latin hypercube).  Optional extra residuals, e.g. ``sqrt(w_mac) * (1 - MAC_ii)``, are
appended through ``extra(x) -> (q,)``.

The uncertainty of the optimum (linearised covariance, 95 % intervals) and its identifiability
(SVD of the column-normalised Jacobian) are computed in :mod:`jointid.identification.uncertainty`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from scipy.optimize import least_squares

from jointid.identification.doe import check_bounds, latin_hypercube
from jointid.errors import ConfigError
from jointid.identification.uncertainty import (IDENTIFIABILITY_RATIO, bound_flags, covariance, identifiability,
                                                physical_values, warn_undetermined)

__all__ = ["IdentifyResult", "identify"]

COST_AGREE_TOL = 1e-6  # starts agreeing with the best cost (absolute, in J units)
_FD_STEP = 1e-6  # coded units, central differences


@dataclass
class IdentifyResult:
    """Outcome of :func:`identify`.

    Attributes
    ----------
    names : list of str
        Parameter names (k).
    x_coded : ndarray (k,)
        Best coded parameters.
    theta : ndarray (k,)
        Physical parameters (``to_physical(x_coded)``); equals ``x_coded`` if no bounds were given.
    ci_lower, ci_upper : ndarray (k,)
        95 % interval of ``theta`` (physical, asymmetric; coded if no bounds were given).
    log10_theta, sd_log10 : ndarray (k,)
        log10 of the physical parameters and their standard deviations (NaN without bounds).
    sd_coded : ndarray (k,)
        Standard deviations in coded units (``inf`` for unidentifiable parameters).
    f_model : ndarray (m,)
        Model frequencies at the optimum, Hz.
    f_meas : ndarray (m,)
        Measured frequencies, Hz.
    residual_pct : ndarray (m,)
        ``100 * (f_model - f_meas) / f_meas``.
    residuals : ndarray (m + q,)
        Weighted relative residuals (and extra residuals) at the optimum.
    cost : float
        ``J = sum(residuals**2)``.
    jacobian : ndarray (m + q, k)
        Jacobian of ``residuals`` w.r.t. the coded parameters at the optimum.
    cov_coded : ndarray (k, k)
        Covariance of ``x_coded``.
    cov_singular : bool
        True when ``J^T J`` is singular (some direction undetermined).
    singular_values : ndarray (k,)
        Singular values of the column-normalised Jacobian, descending.
    condition_number : float
        ``s_max / s_min`` of the column-normalised Jacobian (``inf`` if ``s_min = 0``).
    weak_combination : str or None
        The combination the data cannot identify, e.g.
        ``"0.71*k_normal + 0.70*k_lateral (in log10)"``; None when everything is identifiable.
    weakest_direction : str
        The least well determined combination, always given (same format).
    identifiable : bool
        False when ``1/condition_number < 1e-3``.
    on_bound : list of str
        Parameters within ``1e-3`` (coded) of an optimiser bound.
    n_starts, n_starts_agreeing : int
        Number of starts and how many reached the best cost within ``1e-6``.
    sigma_rel : float
        Relative frequency standard deviation used for the covariance.
    message : str
        Optimiser message of the best start.
    """

    names: list[str]
    x_coded: np.ndarray
    theta: np.ndarray
    ci_lower: np.ndarray
    ci_upper: np.ndarray
    log10_theta: np.ndarray
    sd_log10: np.ndarray
    sd_coded: np.ndarray
    f_model: np.ndarray
    f_meas: np.ndarray
    residual_pct: np.ndarray
    residuals: np.ndarray
    cost: float
    jacobian: np.ndarray
    cov_coded: np.ndarray
    cov_singular: bool
    singular_values: np.ndarray
    condition_number: float
    weak_combination: str | None
    weakest_direction: str
    identifiable: bool
    on_bound: list[str] = field(default_factory=list)
    n_starts: int = 0
    n_starts_agreeing: int = 0
    sigma_rel: float = float("nan")
    message: str = ""

    def to_dict(self) -> dict:
        """JSON-serialisable dict; non-finite numbers become ``None``."""
        out = {}
        for key, val in self.__dict__.items():
            out[key] = _jsonable(val)
        return out


def _jsonable(val):
    if isinstance(val, np.ndarray):
        return _jsonable(val.tolist())
    if isinstance(val, (list, tuple)):
        return [_jsonable(v) for v in val]
    if isinstance(val, (bool, np.bool_)):
        return bool(val)
    if isinstance(val, (int, np.integer)):
        return int(val)
    if isinstance(val, (float, np.floating)):
        return float(val) if math.isfinite(val) else None
    return val


def _n_factors(n_factors, names, lower, bounds) -> int:
    for cand in (n_factors, None if names is None else len(names),
                 None if lower is None else np.size(lower)):
        if cand is not None:
            return int(cand)
    lo = np.asarray(bounds[0])
    if lo.ndim == 1:
        return lo.size
    raise ConfigError("identify: the number of parameters is unknown; pass names, lower/upper "
                      "or n_factors")


def _central_diff(fun: Callable, x: np.ndarray) -> np.ndarray:
    k = x.size
    cols = []
    for i in range(k):
        e = np.zeros(k)
        e[i] = _FD_STEP
        cols.append((np.asarray(fun(x + e), float) - np.asarray(fun(x - e), float))
                    / (2 * _FD_STEP))
    return np.column_stack(cols)


def identify(
    model: Callable[[np.ndarray], np.ndarray],
    f_meas,
    *,
    weights=None,
    jacobian: Callable[[np.ndarray], np.ndarray] | None = None,
    n_starts: int = 16,
    seed: int = 0,
    bounds=(-1.0, 1.0),
    sigma_rel: float = 0.01,
    names: Sequence[str] | None = None,
    lower=None,
    upper=None,
    extra: Callable[[np.ndarray], np.ndarray] | None = None,
    extra_jacobian: Callable[[np.ndarray], np.ndarray] | None = None,
    n_factors: int | None = None,
) -> IdentifyResult:
    # many parameters: the multistart fit's options, keyword with defaults
    # long by its numpydoc and eleven options; the body is one call per step (checks, starts, statistics)
    """Identify coded parameters from measured frequencies.

    Parameters
    ----------
    model : callable
        ``model(x) -> f``: coded parameters (k,) to model frequencies (m,) in Hz.
    f_meas : array_like (m,)
        Measured frequencies in Hz (> 0), matched to the model's modes.
    weights : array_like (m,), optional
        Non-negative weights ``w_i`` (default 1).
    jacobian : callable, optional
        ``jacobian(x) -> df/dx`` (m, k) in Hz per coded unit; central differences otherwise.
    n_starts : int
        Number of local starts (the centre plus ``n_starts - 1`` LHS points).
    seed : int
        Seed of the LHS starts.
    bounds : (lo, hi)
        Coded bounds, scalars or arrays (k,); default the DOE box ``[-1, 1]``.
    sigma_rel : float
        Relative standard deviation of each measured frequency (e.g. 0.01 = 1 %).
    names : sequence of str, optional
        Parameter names (k) used in flags and messages (default ``x0, x1, ...``).
    lower, upper : array_like (k,), optional
        Physical bounds of the coding (see :func:`jointid.identification.doe.to_physical`).  Without them results
        stay in coded units.
    extra : callable, optional
        ``extra(x) -> (q,)`` additional residuals (e.g. ``sqrt(w_mac) * (1 - MAC_ii)``).
    extra_jacobian : callable, optional
        ``extra_jacobian(x) -> (q, k)``, the derivative of ``extra``; central differences otherwise.
    n_factors : int, optional
        Number of parameters if neither names, lower nor array bounds give it.

    Returns
    -------
    IdentifyResult

    Warns
    -----
    NumericalWarning
        A parameter sits on a bound; the data cannot identify some combination; ``J^T J`` singular.
    """
    f_meas = np.asarray(f_meas, dtype=float).reshape(-1)
    m = f_meas.size
    k = _n_factors(n_factors, names, lower, bounds)
    names = [f"x{i}" for i in range(k)] if names is None else [str(s) for s in names]
    w = np.ones(m) if weights is None else np.asarray(weights, dtype=float).reshape(-1)
    lo_b = np.broadcast_to(np.asarray(bounds[0], dtype=float), (k,)).copy()
    hi_b = np.broadcast_to(np.asarray(bounds[1], dtype=float), (k,)).copy()
    _check_inputs(f_meas, w, names, k, lo_b, hi_b, lower, upper, sigma_rel, n_starts)
    lo_p = hi_p = None
    if lower is not None:
        lo_p, hi_p = check_bounds(lower, upper, k)
        if lo_p.size != k:
            raise ConfigError(f"identify: lower/upper have {lo_p.size} entries for {k} parameters; "
                              f"give one physical (lower, upper) pair per parameter")

    residual, residual_jac = _residual_functions(model, f_meas, w, jacobian, (extra, extra_jacobian), k)
    best, n_agree, n_run = _multistart(residual, residual_jac, lo_b, hi_b, n_starts, seed, k)
    x = np.clip(best.x, lo_b, hi_b)

    r = residual(x)
    J = residual_jac(x)
    f_model = np.asarray(model(x), dtype=float).reshape(-1)
    cov, sd, cov_singular, involved = covariance(J, k, sigma_rel)
    sn_full, ratio, condition_number, weakest, half = identifiability(J, k, names, lo_p, hi_p)
    identifiable = bool(ratio >= IDENTIFIABILITY_RATIO)
    warn_undetermined(identifiable, cov_singular, weakest, ratio, names, involved)
    log10_theta, sd_log10, theta, ci_lower, ci_upper = physical_values(x, sd, half, lo_p, k)
    on_bound = bound_flags(x, names, lo_b, hi_b, half, lo_p)

    return IdentifyResult(
        names=names,
        x_coded=x,
        theta=theta,
        ci_lower=ci_lower,
        ci_upper=ci_upper,
        log10_theta=log10_theta,
        sd_log10=sd_log10,
        sd_coded=sd,
        f_model=f_model,
        f_meas=f_meas,
        residual_pct=100.0 * (f_model - f_meas) / f_meas,
        residuals=r,
        cost=float(np.sum(r**2)),
        jacobian=J,
        cov_coded=cov,
        cov_singular=cov_singular,
        singular_values=sn_full,
        condition_number=condition_number,
        weak_combination=None if identifiable else weakest,
        weakest_direction=weakest,
        identifiable=identifiable,
        on_bound=on_bound,
        n_starts=n_run,
        n_starts_agreeing=n_agree,
        sigma_rel=float(sigma_rel),
        message=str(best.message),
    )


def _check_inputs(f_meas, w, names, k, lo_b, hi_b, lower, upper, sigma_rel, n_starts) -> None:
    # many parameters: checks every argument of identify at once, so that one error lists all problems
    """Raise one :class:`ConfigError` listing every problem of the arguments of :func:`identify`."""
    m = f_meas.size
    problems = []
    if m == 0:
        problems.append("identify: no measured frequencies; give at least one matched mode")
    if np.any(~np.isfinite(f_meas)) or np.any(f_meas <= 0):
        problems.append("identify: measured frequencies must be finite and > 0 Hz")
    if w.size != m:
        problems.append(f"identify: {w.size} weights for {m} frequencies; give one weight per mode")
    elif np.any(~np.isfinite(w)) or np.any(w < 0):
        problems.append("identify: weights must be finite and >= 0")
    if len(names) != k:
        problems.append(f"identify: {len(names)} names for {k} parameters")
    if np.any(~(hi_b > lo_b)):
        problems.append("identify: every coded upper bound must exceed its lower bound")
    if (lower is None) != (upper is None):
        problems.append("identify: give both lower and upper physical bounds, or neither")
    if not (sigma_rel > 0 and math.isfinite(sigma_rel)):
        problems.append(f"identify: sigma_rel = {sigma_rel} must be a finite relative std > 0")
    if n_starts < 1:
        problems.append(f"identify: n_starts = {n_starts} must be >= 1")
    if problems:
        raise ConfigError(problems)


def _residual_functions(model, f_meas, w, jacobian, extras, k):
    """``(residual, residual_jac)``: the weighted relative residuals ``sqrt(w) (f - f_meas) / f_meas``
    (then ``extra(x)``) and their Jacobian (m + q, k) w.r.t. the coded parameters.  ``extras``:
    ``(extra, extra_jacobian)``, either may be None."""
    extra, extra_jacobian = extras
    m = f_meas.size
    sw = np.sqrt(w)
    scale = sw / f_meas  # d r_i / d f_i

    def residual(x):
        f = np.asarray(model(x), dtype=float).reshape(-1)
        if f.size != m:
            raise ConfigError(f"identify: the model returns {f.size} frequencies but {m} were "
                              f"measured; match modes before identifying")
        r = scale * (f - f_meas)
        if extra is not None:
            r = np.concatenate([r, np.asarray(extra(x), dtype=float).reshape(-1)])
        return r

    def residual_jac(x):
        if jacobian is not None:
            Jf = np.asarray(jacobian(x), dtype=float).reshape(m, k)
        else:
            Jf = _central_diff(lambda z: np.asarray(model(z), float).reshape(-1), x)
        J = scale[:, None] * Jf
        if extra is not None:
            Je = (_central_diff(lambda z: np.asarray(extra(z), float).reshape(-1), x) if extra_jacobian is None
                  else np.asarray(extra_jacobian(x), dtype=float).reshape(-1, k))
            J = np.vstack([J, Je])
        return J

    return residual, residual_jac


def _multistart(residual, residual_jac, lo_b, hi_b, n_starts, seed, k):
    """Bounded least squares from the centre of the box and ``n_starts - 1`` seeded LHS points.
    Returns ``(best solution, starts agreeing with its cost J, number of starts)``."""
    # Starts: centre of the box first, then a seeded LHS inside the box.
    centre = 0.5 * (lo_b + hi_b)
    starts = [centre]
    if n_starts > 1:
        u = latin_hypercube(n_starts - 1, k, np.random.default_rng(seed))
        starts += list(lo_b + u * (hi_b - lo_b))

    fits = []
    for x0 in starts:
        sol = least_squares(residual, x0, jac=residual_jac, bounds=(lo_b, hi_b), method="trf",
                            x_scale=1.0, ftol=1e-12, xtol=1e-12, gtol=1e-12, max_nfev=200 * k)
        fits.append(sol)
    costs = np.array([2.0 * sol.cost for sol in fits])  # scipy's cost is 0.5 * sum r^2
    best = fits[int(np.argmin(costs))]
    cost = float(2.0 * best.cost)
    n_agree = int(np.sum(np.abs(costs - cost) <= COST_AGREE_TOL * max(1.0, cost)))
    return best, n_agree, len(starts)


