"""Joint damping identified from measured modal damping ratios and the model's joint energy shares.

Per paired mode r the test gives a damping ratio ``zeta_r``; the identified model gives each joint
parameter's (direction's) share of the mode's strain energy, ``e_rj = theta_j phi_r^T K_j phi_r / w_r^2``
(mass-normalised ``phi_r``; :func:`jointid.response.damping.joint_energy_share` of the joint layers,
:func:`jointid.response.drive_point.joint_stiffness`).  Two damping laws are fitted, linear in their
parameters, all >= 0:

``"hysteretic"`` (a loss factor per joint direction, frequency independent)
    ``zeta_r = zeta0 + sum_j eta_j e_rj / 2``;
``"viscous"`` (a dashpot ``C_j = c_j K_j`` per direction, ``c_j`` in s, the ``"joint"`` damping model of
:mod:`jointid.response.damping`)
    ``zeta_r = zeta0 + sum_j c_j w_r e_rj / 2``;

``zeta0`` is the structural damping of everything else (the solids, the fixed joints).  Each law is a
weighted linear least-squares fit with bounds (:func:`scipy.optimize.lsq_linear`), each ratio weighted
by its stated relative uncertainty (conditions.yaml ``damping_uncertainty_pct``; without it, one
relative uncertainty for all, estimated from the scatter of the better law's fit).  The model error
is that of the frequencies (:mod:`jointid.identification.model_error`): estimated once from the better
law (the reference), it inflates both laws' intervals when the fit sits above the stated noise, and
the laws are compared by QAICc at it (AICc when the fit is within its noise).  The 95 % intervals are
``value +- 1.96 sd`` from the covariance at the total uncertainty, cut at 0.

A parameter whose weighted column is nearly a combination of the others over the measured modes
(``R^2 >= COLLINEAR_R2``, uncentred, ``zeta0``'s column included) is reported as not identifiable,
with what it is collinear with, instead of a value, unless the data are precise enough to determine
it all the same (:func:`jointid.identification.collinearity.valued`).

In the identify stage the energy shares come from the FE polish's exact sensitivities at its optimum
(:func:`shares_from_polish`): ``d ln f_r / d log10 theta_j = ln(10) e_rj / 2``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import lsq_linear

from jointid.errors import DataError
from jointid.identification.collinearity import COLLINEAR_R2, collinearity as _collinearity, valued
from jointid.identification.model_error import ModelError, estimate, qaicc, support_text

__all__ = ["COLLINEAR_R2", "LAWS", "JointDamping", "LawFit", "attraction_change", "direction_label",
           "fit_joint_damping", "modal_ratios", "params_entry", "shares_from_polish", "stage_record", "summary_line"]

LAWS = ("hysteretic", "viscous")
Z95 = 1.96


def direction_label(name: str) -> str:
    """Short label of a joint parameter: ``k_normal_N_per_m3`` -> ``normal`` (other names unchanged)."""
    short = name[2:] if name.startswith("k_") else name
    return short[: -len("_N_per_m3")] if short.endswith("_N_per_m3") else short


def shares_from_polish(polish: dict, f_meas_Hz, weights=None) -> np.ndarray:
    """Joint energy shares of the paired modes at the FE polish's optimum, from its Jacobian.

    Parameters
    ----------
    polish : dict
        :func:`jointid.identification.polish.fe_polish` result: ``jacobian_log10`` ``(n_rows, n_params)``
        (rows: the paired modes in measured order, then any misfit rows), ``f_fe`` ``(n_meas,)`` (Hz).
    f_meas_Hz : array_like, shape (n_meas,)
        Measured frequencies (Hz), the polish's targets.
    weights : array_like, shape (n_meas,), optional
        The polish's row weights (``identify.weights``; None: 1).

    Returns
    -------
    ndarray, shape (n_meas, n_params)
        ``e_rj = 2 / ln(10) d ln f_r / d log10 theta_j`` (dimensionless).  On mesh-extrapolated
        frequencies the sensitivity also holds the extrapolation factor's own (small) part.
    """
    f_meas = np.asarray(f_meas_Hz, float)
    w = np.ones(f_meas.size) if weights is None else np.asarray(weights, float)
    J = np.asarray(polish["jacobian_log10"], float)[: f_meas.size]
    scale = np.sqrt(w) * np.asarray(polish["f_fe"], float) / f_meas
    return 2.0 / math.log(10) * J / scale[:, None]


def _design(shares: np.ndarray, freqs_Hz: np.ndarray, law: str) -> np.ndarray:
    """``(n_modes, 1 + n_dirs)``: the column of ``zeta0`` and one per direction (``e/2`` or ``w e/2``)."""
    if law not in LAWS:
        raise ValueError(f"law {law!r}: use one of {', '.join(LAWS)}")
    cols = shares / 2.0 if law == "hysteretic" else shares * (np.pi * freqs_Hz)[:, None]
    return np.column_stack([np.ones(len(shares)), cols])


@dataclass(frozen=True)
class LawFit:
    """One law fitted: values ``x`` ``(1 + n_dirs,)`` (``zeta0``, then ``eta_j`` or ``c_j`` in s),
    covariance at the total uncertainty ``cov``, relative residuals ``e_rel`` ``(n_modes,)`` and the
    chi-square at the total uncertainty ``chi2_total`` and its QAICc."""

    law: str
    x: np.ndarray
    cov: np.ndarray
    e_rel: np.ndarray
    zeta_fit: np.ndarray
    chi2_total: float
    qaicc: float


def _solve(A: np.ndarray, zeta: np.ndarray, sigma_abs: np.ndarray) -> np.ndarray:
    """Bounded (>= 0) weighted linear least squares of ``A x = zeta``."""
    Aw, bw = A / sigma_abs[:, None], zeta / sigma_abs
    if not np.any(Aw):
        return np.zeros(A.shape[1])
    return lsq_linear(Aw, bw, bounds=(0.0, np.inf), method="bvls", tol=1e-14).x


def _finish(law, A, x, zeta, s_rel, me: ModelError) -> LawFit:
    """Covariance, residuals and QAICc of a fit at the model error ``me``."""
    var_abs = zeta ** 2 * me.variances(s_rel)
    cov = np.linalg.pinv((A / var_abs[:, None]).T @ A)
    fit = A @ x
    e_rel = (fit - zeta) / zeta
    chi2 = float(np.sum(e_rel ** 2 / me.variances(s_rel)))
    return LawFit(law, x, cov, e_rel, fit, chi2, qaicc(chi2, len(zeta), A.shape[1]))


@dataclass(frozen=True)
class JointDamping:
    """Joint damping identified from the measured damping ratios of one state.

    Attributes
    ----------
    directions : tuple of str
        Joint parameters (``k_normal_N_per_m3``, ...), labelled by :func:`direction_label` in the record.
    fits : dict
        ``{"hysteretic": LawFit, "viscous": LawFit}``.
    law : str
        The law of lower QAICc.
    model_error : ModelError
        Estimated from the better law's fit (relative to ``zeta``).
    noise_source : str
        Where the relative uncertainty of ``zeta`` came from.
    r2 : dict
        ``{law: ndarray (1 + n_dirs,)}``: each weighted column's uncentred R^2 on the others.
    partner : dict
        ``{law: ndarray (1 + n_dirs,) of int}``: the most collinear other column.
    zeta_meas, freqs_Hz : ndarray, shape (n_modes,)
        Measured damping ratios and the paired modes' frequencies (Hz).
    shares : ndarray, shape (n_modes, n_dirs)
        Joint energy shares of the paired modes.
    """

    directions: tuple
    fits: dict
    law: str
    model_error: ModelError
    noise_source: str
    r2: dict
    partner: dict
    zeta_meas: np.ndarray
    freqs_Hz: np.ndarray
    shares: np.ndarray
    notes: tuple = field(default=())

    def labels(self, law: str) -> list[str]:
        """Record keys of the parameters of ``law``: ``zeta0``, ``eta_<dir>`` or ``c_<dir>_s``."""
        fmt = "eta_{}" if law == "hysteretic" else "c_{}_s"
        return ["zeta0"] + [fmt.format(direction_label(d)) for d in self.directions]

    def identifiable(self, law: str) -> np.ndarray:
        """Per parameter of ``law``: whether it is valued (:func:`jointid.identification.collinearity.valued`)."""
        return valued(self.r2[law], self.fits[law].x, self.fits[law].cov)

    def _law_record(self, law: str) -> dict:
        fit, labels = self.fits[law], self.labels(law)
        ok = self.identifiable(law)
        out = {}
        for j, key in enumerate(labels):
            sd = math.sqrt(max(float(fit.cov[j, j]), 0.0))
            value = float(fit.x[j])
            if ok[j]:
                out.update({key: value, f"{key}_sd": sd, f"{key}_ci95_low": max(0.0, value - Z95 * sd),
                            f"{key}_ci95_high": value + Z95 * sd, f"{key}_at_bound": bool(value <= 0.0)})
                if self.r2[law][j] >= COLLINEAR_R2:
                    out[f"{key}_note"] = (f"collinear with {labels[self.partner[law][j]]} (R^2 = "
                                          f"{self.r2[law][j]:.4f}), determined by the data's precision")
            else:
                out.update({key: None, f"{key}_ci95_low": None, f"{key}_ci95_high": None,
                            f"{key}_note": f"not identifiable: collinear with {labels[self.partner[law][j]]} "
                                           f"over the {len(self.zeta_meas)} measured modes (R^2 = "
                                           f"{self.r2[law][j]:.4f} >= {COLLINEAR_R2})"})
        out.update({"collinearity_r2": dict(zip(labels, map(float, self.r2[law]))),
                    "damping_ratio_fit": fit.zeta_fit.tolist(), "residual_rel": fit.e_rel.tolist(),
                    "chi2_total": fit.chi2_total, "qaicc": fit.qaicc,
                    "covariance": fit.cov.tolist(), "covariance_order": labels})
        return out

    def record(self) -> dict:
        """JSON-ready record: the hysteretic law's values at the top level, both laws in full, the
        comparison, the noise and the model error."""
        other = "viscous" if self.law == "hysteretic" else "hysteretic"
        # both laws have the same parameter count: dQAICc is their difference of chi-square at the total noise
        delta = self.fits[other].chi2_total - self.fits[self.law].chi2_total
        what = "dQAICc" if np.isfinite(self.fits[self.law].qaicc) else "dchi2 (too few modes for QAICc)"
        me = self.model_error
        top = {k: v for k, v in self._law_record("hysteretic").items() if k.startswith(("zeta0", "eta_"))}
        return {**top, "law": self.law,
                "law_note": f"{self.law} fits better by {what} = {delta:.2f} ({support_text(-delta)} supported "
                            f"over {other})",
                "delta_qaicc_other_law": delta, "directions": list(self.directions),
                "n_modes": int(len(self.zeta_meas)), "n_params": len(self.directions) + 1,
                "sigma_noise_rel": me.sigma_noise_rel, "noise_source": self.noise_source,
                "sigma_model_rel": me.sigma_model_rel, "c_hat": me.c_hat, "inflation": me.inflation,
                "model_error_reference": me.reference, "intervals_inflated": me.above_noise,
                "damping_ratio_meas": self.zeta_meas.tolist(), "f_model_Hz": self.freqs_Hz.tolist(),
                **{f"energy_share_{direction_label(d)}": self.shares[:, j].tolist()
                   for j, d in enumerate(self.directions)},
                "hysteretic": self._law_record("hysteretic"), "viscous": self._law_record("viscous"),
                "notes": list(self.notes)}


def fit_joint_damping(zeta, shares, freqs_Hz, directions, *, sigma_rel=None, reference="joint damping"):
    """Fit both damping laws to measured modal damping ratios.

    Parameters
    ----------
    zeta : array_like, shape (n_modes,)
        Measured damping ratios of the paired modes (of critical, > 0).
    shares : array_like, shape (n_modes, n_dirs)
        Joint energy shares ``e_rj`` of the paired modes (dimensionless, in [0, 1]).
    freqs_Hz : array_like, shape (n_modes,)
        Natural frequencies of the paired modes (Hz), for the viscous law.
    directions : sequence of str, length n_dirs
        Joint parameter names of the columns of ``shares``.
    sigma_rel : float or array_like, shape (n_modes,), optional
        Stated 1-sigma relative uncertainty of each ratio (0.05 = 5 % of zeta); None: unknown, one
        for all, estimated from the scatter of the better law.
    reference : str
        Name of the fit in the model-error record.

    Returns
    -------
    JointDamping
    """
    zeta = np.asarray(zeta, float)
    shares = np.atleast_2d(np.asarray(shares, float))
    f = np.asarray(freqs_Hz, float)
    n, k = len(zeta), shares.shape[1] + 1
    if not (np.all(np.isfinite(zeta)) and np.all(zeta > 0)):
        raise DataError(f"damping ratios {zeta.tolist()}: every one must be finite and > 0")
    if shares.shape != (n, len(directions)) or f.shape != (n,):
        raise DataError(f"energy shares {shares.shape} and frequencies {f.shape} do not match {n} damping "
                        f"ratios and {len(directions)} directions")
    stated = sigma_rel is not None
    if n < k + (0 if stated else 1):
        raise DataError(f"{n} measured damping ratios for {k} parameters (zeta0 and one per direction)"
                        + ("" if stated else " and their unstated noise") + ": measure more modes")
    s = np.broadcast_to(np.asarray(sigma_rel if stated else 1.0, float), (n,)).astype(float)
    designs = {law: _design(shares, f, law) for law in LAWS}
    xs = {law: _solve(A, zeta, s * zeta) for law, A in designs.items()}
    e2 = {law: float(np.sum(((A @ xs[law] - zeta) / zeta / s) ** 2)) for law, A in designs.items()}
    best = min(LAWS, key=lambda law: e2[law])
    notes = []
    if not stated:  # one relative uncertainty, from the better law's scatter
        s = np.full(n, max(math.sqrt(e2[best] / max(n - k, 1)), 1e-12))  # 1e-12: an exact fit
        noise_source = f"estimated from the scatter of the {best} fit (no damping_uncertainty_pct stated)"
    else:
        noise_source = "stated (damping_uncertainty_pct: per mode in modes.csv, or conditions.yaml)"
    r = (designs[best] @ xs[best] - zeta) / zeta / s
    me = estimate(r, s, k, reference=f"{reference}, {best} law")
    if me.above_noise:
        notes.append(f"the {best} fit sits above the stated damping noise (c_hat = {me.c_hat:.2f}): the intervals "
                     f"are inflated by a model error of {100 * me.sigma_model_rel:.3g} % of zeta per mode")
    if n <= k:
        notes.append(f"{n} measured damping ratios for {k} parameters: no degree of freedom is left, the "
                     "intervals rest on the stated noise alone")
    fits = {law: _finish(law, A, xs[law], zeta, s, me) for law, A in designs.items()}
    law = min(LAWS, key=lambda name: fits[name].chi2_total)  # = the lower QAICc (equal parameter counts)
    col = {law_: _collinearity(A / (s * zeta)[:, None]) for law_, A in designs.items()}
    return JointDamping(tuple(directions), fits, law, me, noise_source, {k_: v[0] for k_, v in col.items()},
                        {k_: v[1] for k_, v in col.items()}, zeta, f, shares, tuple(notes))


def modal_ratios(result: JointDamping, shares, freqs_Hz, law: str | None = None) -> np.ndarray:
    """Damping ratio of any mode under an identified law (default: the better one).

    Parameters
    ----------
    result : JointDamping
    shares : array_like, shape (n_modes, n_dirs)
        Joint energy shares of the modes, columns in ``result.directions`` order.
    freqs_Hz : array_like, shape (n_modes,)
        Their natural frequencies (Hz).
    law : {"hysteretic", "viscous"}, optional

    Returns
    -------
    ndarray, shape (n_modes,)
        ``zeta0 + sum_j eta_j e_rj / 2`` (or the viscous law's), equivalent viscous ratios.
    """
    law = law or result.law
    return _design(np.atleast_2d(np.asarray(shares, float)), np.asarray(freqs_Hz, float), law) @ result.fits[law].x


def attraction_change(off: dict, on: dict) -> dict:
    """Whether the attraction changed each hysteretic parameter: ``on - off`` with its 95 % interval.

    Parameters
    ----------
    off, on : dict
        :meth:`JointDamping.record` of the state without and with the attraction (independent fits).

    Returns
    -------
    dict
        Per parameter ``<key>_change``, ``<key>_change_ci95_low/high`` and ``<key>_changed`` (the
        interval excludes 0); None where either state cannot identify it.
    """
    out = {}
    for key in off["hysteretic"]["covariance_order"]:
        a, b = off.get(key), on.get(key)
        if a is None or b is None or key not in on["hysteretic"]["covariance_order"]:
            out[f"{key}_change"] = None
            continue
        d = b - a
        sd = math.hypot(off[f"{key}_sd"], on[f"{key}_sd"])
        out.update({f"{key}_change": d, f"{key}_change_ci95_low": d - Z95 * sd,
                    f"{key}_change_ci95_high": d + Z95 * sd, f"{key}_changed": bool(abs(d) > Z95 * sd)})
    return out


def stage_record(folder: str, state: str, names, polish, f_meas_Hz, weights=None, *, extrapolated=False):
    """The ``joint_damping`` record of ``params.json``, or None when the state's dataset has no damping ratios.

    ``folder``: the state's dataset folder (:func:`jointid.config.dataset_folder`); ``names``: the identified joint
    parameters (the polish's columns); ``polish``: the FE polish
    (:func:`jointid.identification.polish.fe_polish`; None: no energy shares, the record says so);
    ``f_meas_Hz`` ``(n_meas,)``: the measured frequencies in the dataset's mode order; ``weights``:
    ``identify.weights``; ``extrapolated``: the polish fitted mesh-extrapolated frequencies.  Returns
    ``{"identified": True, **JointDamping.record(), "shares_source"}``, or ``{"identified": False,
    "note"}`` when the ratios cannot be used.
    """
    from jointid.data.dataset import read_dataset

    ds = read_dataset(folder)
    zeta = ds.damping(state) if state in ds.states else None
    if zeta is None:
        return None
    if polish is None:
        return {"identified": False, "note": "joint damping needs the energy shares of the FE polish "
                                             "(identify.fe_polish: true)"}
    if len(zeta) != len(f_meas_Hz) or not np.all(np.isfinite(zeta) & (zeta > 0)):
        return {"identified": False, "note": "not every measured mode has a damping ratio > 0"}
    # per mode where modes.csv gives it (an EMA's damping_uncertainty_pct), else conditions.yaml's one number
    sigma_pct = ds.mode_uncertainty_pct(state, "damping")
    if sigma_pct is None and ds.conditions.get("damping_uncertainty_pct") is not None:
        sigma_pct = float(ds.conditions["damping_uncertainty_pct"])
    try:
        res = fit_joint_damping(zeta, shares_from_polish(polish, f_meas_Hz, weights), polish["f_fe"], list(names),
                                sigma_rel=None if sigma_pct is None else np.asarray(sigma_pct, float) / 100,
                                reference=f"identify[{state}] joint damping")
    except DataError as exc:
        return {"identified": False, "note": str(exc)}
    return {"identified": True, **res.record(), "shares_source": "FE polish sensitivities at its optimum"
            + (" (mesh-extrapolated: with the extrapolation factors' own part)" if extrapolated else "")}


def summary_line(rec: dict) -> str:
    """One log line of a ``joint_damping`` record."""
    if not rec.get("identified"):
        return f"joint damping not identified: {rec.get('note', '')}"
    vals = [f"{k} = {'not identifiable' if rec[k] is None else format(rec[k], '.4g')}"
            + ("" if rec[k] is None else f" [{rec[k + '_ci95_low']:.3g}, {rec[k + '_ci95_high']:.3g}]")
            for k in rec["hysteretic"]["covariance_order"]]
    return (f"joint damping (hysteretic): {', '.join(vals)}; {rec['law_note']}; c_hat {rec['c_hat']:.2f}"
            + (f", intervals inflated by sigma_m {100 * rec['sigma_model_rel']:.3g} %" if rec["intervals_inflated"]
               else ""))


def params_entry(folder: str, state: str, names, polish, f_meas_Hz, weights=None, edge=None, log=None) -> dict:
    """``{"joint_damping": record}`` for ``params.json`` (:func:`stage_record`, logged by ``log``), ``{}``
    when the dataset ``folder`` has no damping ratios (frequency-only data: ``params.json`` as without
    this step); ``edge``: the polish's mesh-extrapolation record (None: none)."""
    rec = stage_record(folder, state, names, polish, f_meas_Hz, weights, extrapolated=edge is not None)
    if rec is not None and log is not None:
        log(f"identify[{state}]: " + summary_line(rec))
    return {} if rec is None else {"joint_damping": rec}
