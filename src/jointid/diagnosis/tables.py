"""Result tables of the diagnosis: per-state errors, ranking, fitted parameters, comparison, drift.

See docs/effects.md.  Every function returns a :class:`pandas.DataFrame` (or rows of one); none
changes the solver state except :func:`compare_tables` and :func:`drift_table`, which solve.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd

from jointid.correlate import pairing as correlate
from jointid.correlate.mac import mac
from jointid.diagnosis.results import log_interval
from jointid.diagnosis.fitting import Diagnoser, Fit
from jointid.diagnosis.variants import EffectSpec, Variant
from jointid.errors import NumericalWarning
from jointid.fe.describe import describe_modes
from jointid.fe.fem import Model
from jointid.fe.reduced import Solution

DRIFT_COLUMNS = ["parameter", "state", "value", "ci95_low", "ci95_high", "drift_pct", "z"]


def state_errors_table(diag: Diagnoser, fit: Fit, label: str) -> list[dict]:
    """Ladder rows of ``fit``: per state max/RMS error (%) with the fit's chi2, n, k, AICc, p-value."""
    rows = []
    for s in fit.state_summary(diag.data):
        rows.append({"variant": label, **s, "chi2": fit.chi2, "n_data": fit.n, "n_params": fit.k,
                     "aicc": fit.aicc, "p_value": fit.p_value})
    return rows


def ranking_frame(rows: list[dict]) -> pd.DataFrame:
    """The candidate ranking: refitted candidates first (explaining ones, then by delta QAICc: delta
    AICc at the total uncertainty, :mod:`jointid.diagnosis.judging`), then the rest by score; ``rank``
    numbers the rows from 1."""
    cols = ["rank", "effect", "explained_fraction", "score", "p_value", "delta_aicc", "delta_qaicc", "weight",
            "support", "removed_fraction", "explains", "parameter",
            "unit", "estimate", "ci95_low", "ci95_high", "interval_scale", "linear_estimate", "fit_chi2", "fit_p_value",
            "max_abs_error_pct_after", "rms_error_pct_after", "between_states_fraction",
            "between_states_p_value", "collinearity", "title", "note", "identifiable", "enable_with"]
    df = pd.DataFrame(rows)
    for c in cols:
        if c not in df:
            df[c] = np.nan
    refitted = df["delta_aicc"].notna()
    a = df[refitted].sort_values(["explains", "delta_qaicc"], ascending=[False, True], kind="stable")
    b = df[~refitted].sort_values("score", ascending=False, kind="stable")
    out = pd.concat([a, b], ignore_index=True)
    out["rank"] = np.arange(1, len(out) + 1)
    out["explains"] = out["explains"].astype(object).where(out["explains"].notna(), False).astype(bool)
    for c in ("note", "identifiable", "enable_with", "support"):  # text columns: empty, never NaN
        out[c] = out[c].astype(object).where(out[c].notna(), "")
    return out[cols]


def parameter_table(fits: dict) -> pd.DataFrame:
    """Fitted parameters of every fit (physical units) with 95 % intervals (widened by the fit's
    :meth:`~jointid.diagnosis.results.Fit.interval_scale`) and an on-bound flag."""
    rows = []
    for label, f in fits.items():
        cov = f.scaled_covariance()
        for j, (lab, val) in enumerate(f.variant.physical(f.x).items()):
            sd = float(np.sqrt(max(cov[j, j], 0.0)))
            if j < f.variant.p:
                lo, hi = log_interval(val, sd)
            else:
                p = f.variant.slots[j - f.variant.p][1]
                t = float(f.x[j])
                a, b = max(t - 1.96 * sd, p.t_bounds[0]), t + 1.96 * sd
                v = sorted([p.from_t(a) if a != 0 else p.null, p.from_t(b)])
                lo, hi = v
            rows.append({"variant": label, "parameter": lab, "value": val, "ci95_low": lo, "ci95_high": hi,
                         "interval_scale": f.interval_scale(),
                         "on_bound": bool(min(f.x[j] - f.variant.lower[j], f.variant.upper[j] - f.x[j]) < 1e-6)})
    return pd.DataFrame(rows)


def mode_descriptions(diag: Diagnoser, sol: Solution) -> list[str] | None:
    """Plain-language description of each mode of ``sol`` (``jointid.fe.describe``).  With a memo
    (``diagnosis.reuse_subspace``) the descriptions at a point described before are read from it."""
    parts = (diag.solver.point_key(sol.kc, sol.mc), len(sol.freqs_Hz))
    return diag.remembered("mode_descriptions", parts, lambda: _describe(diag, sol),
                           lambda desc: [str(d) for d in desc], list)


def _describe(diag: Diagnoser, sol: Solution) -> list[str] | None:
    sysm = diag.system
    m = sysm.model
    pseudo = Model(stiffness=sysm.stiffness, mass=sysm.mass, fixed=sysm.fixed, probe=sysm.probe,
                   doflocs=m.doflocs, dof_part=m.dof_part, meta=m.meta)
    try:
        return describe_modes(pseudo, diag.solver.full_phi(sol), sol.kc, sol.mc)["description"].tolist()
    except Exception as exc:  # descriptions are a convenience, never a reason to fail
        warnings.warn(f"mode descriptions unavailable ({exc})", NumericalWarning)
        return None


def compare_tables(diag: Diagnoser, variant: Variant, x):
    """Per-mode errors (fresh pairing), MAC matrices and shape residuals of ``variant`` at ``x``."""
    sols = diag.solve_states(variant, x)
    pairings = diag.pair(sols)
    frames, macs, shapes = [], {}, []
    for d, s, p in zip(diag.data, sols, pairings):
        desc = mode_descriptions(diag, s)
        frames.append(correlate.frequency_errors(d.name, d.f_meas, s.freqs_Hz, p, desc))
        if d.shapes is not None:
            macs[d.name] = mac(d.shapes, s.shapes)
            shapes.append(correlate.shape_residuals(d.name, d.shapes, s.shapes, p, diag.system.labels))
    sh = pd.concat(shapes, ignore_index=True) if shapes else correlate.shape_residuals("", None, None, None, [])
    return pd.concat(frames, ignore_index=True), macs, sh


def drift_table(diag: Diagnoser, current: Fit, log, skip: bool = False) -> pd.DataFrame:
    """Joint parameters fitted per state (effects fixed at their fitted values) and their drift."""
    if len(diag.data) < 2 or skip:
        return pd.DataFrame(columns=DRIFT_COLUMNS)
    var = current.variant
    theta, vals = var.unpack(current.x)
    fixed_specs = [EffectSpec(s.effect, v, s.options, []) for s, v in zip(var.effects, vals)]
    one = Variant(diag.system, diag.settings, fixed_specs, theta_fixed=var.theta_fixed)
    rows = []
    for k, d in enumerate(diag.data):
        sub = Diagnoser(diag.system, diag.settings, [d], n_modes=diag.n_modes, solver=diag.solver, memo=diag.memo,
                        log=log)
        if sum(np.asarray(current.ev.index[k]) >= 0) <= one.n_params:
            continue
        f = sub.fit(one, current.x[: one.n_params], index=[current.ev.index[k]])
        cov = f.scaled_covariance()  # a drift is judged against what the fit leaves, not the noise alone
        for j, n in enumerate(one.joint_names):
            sd = float(np.sqrt(max(cov[j, j], 0.0)))
            lo, hi = log_interval(math.exp(f.x[j]), sd)
            rows.append({"parameter": n, "state": d.name, "value": math.exp(f.x[j]),
                         "ci95_low": lo, "ci95_high": hi,
                         "ln_value": float(f.x[j]), "ln_sd": sd})
    df = pd.DataFrame(rows)
    if df.empty:
        return pd.DataFrame(columns=DRIFT_COLUMNS)
    out = []
    for n, g in df.groupby("parameter", sort=False):
        r0 = g.iloc[0]
        for _, r in g.iterrows():
            z = (r.ln_value - r0.ln_value) / math.sqrt(r.ln_sd ** 2 + r0.ln_sd ** 2) if r.name != r0.name else 0.0
            out.append({"parameter": n, "state": r.state, "value": r.value, "ci95_low": r.ci95_low,
                        "ci95_high": r.ci95_high, "drift_pct": 100 * (r.value / r0.value - 1), "z": z,
                        "significant": bool(abs(z) > 2.0)})
    return pd.DataFrame(out)
