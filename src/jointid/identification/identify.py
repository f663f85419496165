"""Parameter identification: fit coded joint parameters to measured natural frequencies.

Generic over the model: ``model(x_coded) -> freq_Hz`` with ``x_coded`` of shape ``(k,)`` and the
result of shape ``(m,)`` (usually a fitted :class:`jointid.identification.surface.Surface`, or the FE model itself).

Objective (PHYSICS.md, "Response-surface updating")::

    r_i(x) = sqrt(w_i) * (f_i(x) - f_meas_i) / f_meas_i,     J(x) = sum_i r_i^2  (+ sum extra(x)^2)

minimised by bounded multi-start ``scipy.optimize.least_squares`` (starts: the centre of the box and
a seeded Latin hypercube).  Optional extra residuals, e.g. ``sqrt(w_mac) * (1 - MAC_ii)``, are
appended through ``extra(x) -> (q,)``.

Uncertainty (linearised at the optimum).  Each measured frequency has relative standard deviation
``sigma_rel / sqrt(w_i)`` (the weights are relative precisions; unit weights mean every frequency
has ``sigma_rel``), extra residuals are taken to carry the same ``sigma_rel``.  With ``J`` the
Jacobian of the weighted relative residuals (``J^T J = J_rel^T W J_rel``)::

    cov(x) = sigma_rel^2 * (J^T J)^+        (coded units, pseudo-inverse)

95 % intervals are ``x +- 1.96 sd`` in coded units, i.e. symmetric in log10 of the parameter and
asymmetric in the physical parameter.  Directions that the data do not determine (zero singular
values of ``J``) get infinite variance rather than the pseudo-inverse's zero, so the parameters
involved get unbounded intervals (``0 .. inf`` physically).

Identifiability (PHYSICS.md, "Telling the user which effect is missing"): SVD of the
column-normalised Jacobian; if ``s_min / s_max < 1e-3`` the right singular vector of ``s_min`` names
the combination of parameters that the data cannot resolve.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from scipy.optimize import least_squares

from jointid.identification.doe import check_bounds, latin_hypercube
from jointid.errors import ConfigError, NumericalWarning

__all__ = ["IdentifyResult", "identify", "IDENTIFIABILITY_RATIO", "BOUND_TOL"]

IDENTIFIABILITY_RATIO = 1e-3  # flag s_min/s_max below this
BOUND_TOL = 1e-3  # coded distance to a bound counted as "on the bound"
COST_AGREE_TOL = 1e-6  # starts agreeing with the best cost (absolute, in J units)
Z95 = 1.959963984540054
_FD_STEP = 1e-6  # coded units, central differences
CONFIG_PREFIX = "joints.parameters"


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


def _fmt_num(v: float) -> str:
    s = f"{v:.3g}"
    if "e" in s:
        mant, exp = s.split("e")
        s = f"{mant}e{int(exp)}"
    return s


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
    n_factors: int | None = None,
) -> IdentifyResult:
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
        ``extra(x) -> (q,)`` additional residuals (e.g. ``sqrt(w_mac) * (1 - MAC_ii)``);
        differentiated by central differences.
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
    if lower is not None:
        lo_p, hi_p = check_bounds(lower, upper, k)
        if lo_p.size != k:
            raise ConfigError(f"identify: lower/upper have {lo_p.size} entries for {k} parameters; "
                              f"give one physical (lower, upper) pair per parameter")

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
            J = np.vstack([J, _central_diff(lambda z: np.asarray(extra(z), float).reshape(-1), x)])
        return J

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
    x = np.clip(best.x, lo_b, hi_b)

    r = residual(x)
    J = residual_jac(x)
    f_model = np.asarray(model(x), dtype=float).reshape(-1)

    # --- covariance (coded) through the SVD of J, undetermined directions -> infinite variance
    _, sv, Vt = np.linalg.svd(J, full_matrices=True)
    s_full = np.zeros(k)
    s_full[: min(sv.size, k)] = sv[:k]
    V = Vt.T
    tol = max(J.shape) * np.finfo(float).eps * (s_full.max() if s_full.size else 0.0)
    null = s_full <= tol
    cov = sigma_rel**2 * (V[:, ~null] / s_full[~null] ** 2) @ V[:, ~null].T
    var = np.diag(cov).copy()
    cov_singular = bool(np.any(null))
    if cov_singular:
        involved = np.any(np.abs(V[:, null]) > 1e-6, axis=1)
        var[involved] = np.inf
    sd = np.sqrt(var)

    # --- identifiability on the column-normalised Jacobian
    norms = np.linalg.norm(J, axis=0)
    Jn = J / np.where(norms > 0, norms, 1.0)
    _, sn, Vnt = np.linalg.svd(Jn, full_matrices=True)
    sn_full = np.zeros(k)
    sn_full[: min(sn.size, k)] = sn[:k]
    ratio = sn_full[-1] / sn_full[0] if sn_full[0] > 0 else 0.0
    condition_number = float(np.inf if ratio == 0 else 1.0 / ratio)
    v_weak = Vnt[-1] / np.where(norms > 0, norms, 1.0)  # back to coded coordinates
    if lower is not None:
        half = 0.5 * (np.log10(hi_p) - np.log10(lo_p))  # d log10(theta) / dx
        weakest = _combination(v_weak * half, names, "in log10")
    else:
        half = None
        weakest = _combination(v_weak, names, "in coded units")
    identifiable = bool(ratio >= IDENTIFIABILITY_RATIO)
    if not identifiable:
        warnings.warn(
            f"identify: {weakest} is not identifiable from these data (singular value ratio "
            f"{ratio:.1e} < {IDENTIFIABILITY_RATIO:g}); fix one of these parameters, add modes or "
            f"mode shapes, or reparameterise"
            + (f"; J^T J is singular, so the intervals of "
               f"{', '.join(n for n, b in zip(names, involved) if b)} are unbounded"
               if cov_singular else ""),
            NumericalWarning, stacklevel=2)
    elif cov_singular:
        warnings.warn(
            f"identify: J^T J is numerically singular; the intervals of "
            f"{', '.join(n for n, b in zip(names, involved) if b)} are unbounded",
            NumericalWarning, stacklevel=2)

    # --- physical values and intervals
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

    # --- bound flags
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
                    NumericalWarning, stacklevel=2)
                break

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
        n_starts=len(starts),
        n_starts_agreeing=n_agree,
        sigma_rel=float(sigma_rel),
        message=str(best.message),
    )
