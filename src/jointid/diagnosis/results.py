"""Results of evaluating and fitting a model variant (docs/effects.md).

* :class:`Evaluation` — residuals, Jacobian, solutions and pairing of a variant at a parameter vector;
* :class:`Fit` — a fitted variant: chi-square, p-value, AICc, covariance, per-state errors and the
  unpaired, clearly visible model modes (misfits).

Produced by :class:`jointid.diagnosis.fitting.Diagnoser`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jointid.diagnosis.statistics import aicc, chi2_p_value
from jointid.diagnosis.variants import StateData, Variant

__all__ = ["Evaluation", "Fit", "chi2_at", "frequency_rows", "refit_row", "row_sigma", "row_weights"]


@dataclass
class Evaluation:
    """Residuals and Jacobian of a variant at ``x`` over all states."""

    x: np.ndarray
    r: np.ndarray
    J: np.ndarray
    solutions: list
    index: list  # per state: model mode index per measured mode (-1 unpaired)
    rows: list  # per residual: (state number, measured mode number)
    f_model: list  # per state: model frequency per measured mode (NaN unpaired)
    misfits: list = None  # per state: (model modes, nearest measured Hz, model Hz) of the unpaired visible modes
    n_scales: int = 0  # best scales of the shape rows (one per measured shape: nuisance parameters)


def frequency_rows(ev: Evaluation) -> np.ndarray:
    """Which residual rows are frequency rows (shape rows, :mod:`jointid.diagnosis.shape_residuals`,
    carry a negative mode number): the model error weights these only."""
    return np.array([mode >= 0 for _, mode in ev.rows], bool)


def row_sigma(ev: Evaluation, data: list[StateData]) -> np.ndarray:
    """Stated relative frequency uncertainty of every frequency row of an evaluation (the rows of
    :func:`frequency_rows`; all rows without shape rows)."""
    return np.array([data[si].sigma_rel for si, mode in ev.rows if mode >= 0], float)


def chi2_at(ev: Evaluation, data: list[StateData], me) -> float:
    """Chi-square at the total uncertainty of :class:`ModelError` ``me``: the frequency rows at their
    stated noise plus the model error, the shape rows at their stated (or estimated) shape noise."""
    f = frequency_rows(ev)
    if f.all():
        return me.chi2_total(ev.r, row_sigma(ev, data))
    rs = ev.r[~f]
    return me.chi2_total(ev.r[f], row_sigma(ev, data)) + float(rs @ rs)


def row_weights(ev: Evaluation, data: list[StateData], me) -> np.ndarray:
    """Per residual row, the weight of its chi-square contribution at the total uncertainty of ``me``
    (:meth:`ModelError.row_weights` for the frequency rows, 1 for the shape rows)."""
    f = frequency_rows(ev)
    w = np.ones(len(ev.r))
    w[f] = me.row_weights(row_sigma(ev, data))
    return w


@dataclass
class Fit:
    """A fitted variant: parameters, residuals, chi-square, AICc, covariance, per-state errors."""

    variant: Variant
    ev: Evaluation
    pairings: list
    preload_profile: dict | None = None  # em_preload's block preload when profiled (jointid.diagnosis.preload)

    @property
    def x(self):
        """The fitted parameter vector."""
        return self.ev.x

    @property
    def chi2(self) -> float:
        """Chi-square ``r^T r`` of the sigma-normalised residuals."""
        return float(self.ev.r @ self.ev.r)

    @property
    def n(self) -> int:
        """Number of residuals, less the best scales of the shape rows (each takes one row's freedom)."""
        return len(self.ev.r) - self.ev.n_scales

    @property
    def k(self) -> int:
        """Number of fitted parameters."""
        return self.variant.n_params

    @property
    def dof(self) -> int:
        """Degrees of freedom ``n - k`` (at least 1)."""
        return max(self.n - self.k, 1)

    @property
    def p_value(self) -> float:
        """Probability of a chi-square at least this large if the variant were true (noise only)."""
        return chi2_p_value(self.chi2, self.dof)

    @property
    def aicc(self) -> float:
        """Corrected Akaike criterion of the fit (sigma known), :func:`statistics.aicc`."""
        return aicc(self.chi2, self.n, self.k)

    def covariance(self) -> np.ndarray:
        """Covariance of ``x``: ``(J^T J)^+`` (residuals in units of sigma): right when the model fits
        within the noise; the reported intervals use :meth:`scaled_covariance`."""
        J = self.ev.J
        return np.linalg.pinv(J.T @ J)

    def interval_scale(self, extra_params: int = 0) -> float:
        """``max(1, sqrt(chi2 / dof))``: how much wider than the noise alone the intervals are taken.
        A fit worse than the measurement uncertainty misses something the noise does not cover, and
        its local curvature then understates how far the parameters could move (in a flat valley
        far above the noise, by the same factor).  ``extra_params`` counts parameters chosen
        outside ``x`` (e.g. a profiled preload): they take degrees of freedom too."""
        dof = max(self.n - self.k - extra_params, 1)
        return max(1.0, math.sqrt(self.chi2 / dof))

    def scaled_covariance(self, extra_params: int = 0) -> np.ndarray:
        """:meth:`covariance` times :meth:`interval_scale` squared: the covariance every reported
        95 % interval of the diagnosis comes from (as the identification's and the hypotheses')."""
        return self.covariance() * self.interval_scale(extra_params) ** 2

    def row_sigma(self, data: list[StateData]) -> np.ndarray:
        """Stated relative frequency uncertainty of every residual row (:func:`row_sigma`)."""
        return row_sigma(self.ev, data)

    def errors_pct(self, data: list[StateData]) -> list[np.ndarray]:
        """Frequency error (%) per measured mode and state (NaN unpaired)."""
        return [100 * (fm - d.f_meas) / d.f_meas for fm, d in zip(self.ev.f_model, data)]

    def misfits_pct(self) -> list[np.ndarray]:
        """Per state: the signed misfit (%) of each unpaired, clearly visible model mode (model minus
        the nearest measured mode)."""
        return [100 * (fm - t) / t for _, t, fm in (self.ev.misfits or [])]

    def unpaired_visible(self, data: list[StateData]) -> list[dict]:
        """The unpaired, clearly visible model modes of every state: state, model mode (1-based),
        model and nearest measured frequency (Hz), misfit (%)."""
        out = []
        for d, (cols, tgt, fm) in zip(data, self.ev.misfits or []):
            for c, t, f in zip(cols, tgt, fm):
                out.append({"state": d.name, "model_mode": int(c) + 1, "freq_Hz": float(f),
                            "target_Hz": float(t), "misfit_pct": float(100 * (f - t) / t)})
        return out

    def state_summary(self, data: list[StateData]) -> list[dict]:
        """Per state: number of paired modes, max and RMS error (%) over the paired modes and the
        misfits (unpaired, clearly visible model modes, counted as errors), and the misfit count."""
        out = []
        mis = self.misfits_pct() or [np.zeros(0)] * len(data)
        for d, e, m in zip(data, self.errors_pct(data), mis):
            e = e[np.isfinite(e)]
            a = np.concatenate([e, m])
            out.append({"state": d.name, "n_paired": len(e), "n_unpaired_visible": len(m),
                        "max_abs_error_pct": float(np.abs(a).max()) if len(a) else np.nan,
                        "rms_error_pct": float(np.sqrt(np.mean(a ** 2))) if len(a) else np.nan})
        return out


def refit_row(f: Fit, current: Fit, data: list[StateData], alpha: float, extra_params: int = 0) -> dict:
    """Ranking columns of a candidate's refit ``f`` (its one parameter is the last of ``x``) against
    the ``current`` model: delta AICc, chi-square and p-value, whether it explains the data, the
    estimate with its 95 % interval (physical units) and the errors after.

    ``extra_params`` counts parameters profiled outside ``x`` (e.g. a preload chosen on a grid): they
    enter the AICc and the degrees of freedom.
    """
    cov = f.scaled_covariance(extra_params)
    j = f.variant.n_params - 1
    p0 = f.variant.slots[-1][1]
    t, sd = float(f.x[j]), float(np.sqrt(max(cov[j, j], 0.0)))
    lo_t, hi_t = max(t - 1.96 * sd, p0.t_bounds[0]), min(t + 1.96 * sd, p0.t_bounds[1])
    vals = sorted([p0.from_t(lo_t) if lo_t != 0 else p0.null, p0.from_t(hi_t)])
    summ = [s for s in f.state_summary(data) if np.isfinite(s["max_abs_error_pct"])]
    k = f.k + extra_params
    p_value = chi2_p_value(f.chi2, max(f.n - k, 1))
    return {"delta_aicc": aicc(f.chi2, f.n, k) - current.aicc, "fit_chi2": f.chi2, "fit_p_value": p_value,
            "fit_n_data": f.n, "fit_n_params": k,
            "explains": bool(p_value >= alpha), "estimate": p0.from_t(t), "ci95_low": vals[0],
            "ci95_high": vals[1], "interval_scale": f.interval_scale(extra_params),
            "max_abs_error_pct_after": max(s["max_abs_error_pct"] for s in summ) if summ else np.nan,
            "rms_error_pct_after": float(np.sqrt(np.mean([s["rms_error_pct"] ** 2 for s in summ]))) if summ else np.nan}
