"""Results of evaluating and fitting a model variant (docs/effects.md).

* :class:`Evaluation` — residuals, Jacobian, solutions and pairing of a variant at a parameter vector;
* :class:`Fit` — a fitted variant: chi-square, p-value, AICc, covariance, per-state errors and the
  unpaired, clearly visible model modes (misfits).

Produced by :class:`jointid.diagnosis.fitting.Diagnoser`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from jointid.diagnosis.criteria import aicc, chi2_p_value
from jointid.diagnosis.variants import StateData, Variant
from jointid.identification.model_error import ModelError, cluster_factor, estimate

__all__ = ["Evaluation", "Fit", "chi2_at", "log_interval", "frequency_rows", "refit_row", "row_known", "row_sigma",
           "whitener", "block_error"]


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
    sigma: np.ndarray | None = None  # per row: its stated uncertainty (frequency rows relative, shape rows
    # as a fraction of the mode's RMS); r = error / sigma
    known: np.ndarray | None = None  # per row: its known error (the mesh's; frequency rows relative, shape rows
    # as a fraction of the mode's RMS)
    known_corr: np.ndarray | None = None  # (frequency rows, frequency rows): the known errors' correlation, the
    # MAC of the rows' model modes (a mode's mesh error is the same in every state); None: independent


def log_interval(value: float, sd: float) -> tuple[float, float]:
    """The 95 % interval ``value * exp(-+1.96 sd)`` of a log-parametrised value with standard deviation
    ``sd`` (natural-log units); a parameter the data barely constrain gets ``(0, inf)`` instead of an
    overflow."""
    z = 1.96 * float(sd)
    if not np.isfinite(z) or z > 700.0:
        return 0.0, math.inf
    return value * math.exp(-z), value * math.exp(z)


def frequency_rows(ev: Evaluation) -> np.ndarray:
    """Which residual rows are frequency rows (shape rows, :mod:`jointid.diagnosis.shape_residuals`,
    carry a negative mode number).  An evaluation without row labels has frequency rows only."""
    if len(ev.rows) != len(ev.r):
        return np.ones(len(ev.r), bool)
    return np.array([mode >= 0 for _, mode in ev.rows], bool)


def row_sigma(ev: Evaluation, data: list[StateData] | None = None) -> np.ndarray:
    """Stated relative frequency uncertainty of every frequency row of an evaluation (the rows of
    :func:`frequency_rows`; all rows without shape rows)."""
    f = frequency_rows(ev)
    if ev.sigma is not None:
        return np.asarray(ev.sigma, float)[f]
    return np.array([data[si].noise_rms() for si, mode in ev.rows if mode >= 0], float)


def row_known(ev: Evaluation) -> np.ndarray:
    """Known error (the mesh's, relative) of every frequency row (zeros where none is known)."""
    f = frequency_rows(ev)
    return np.zeros(int(f.sum())) if ev.known is None else np.asarray(ev.known, float)[f]


def row_known_corr(ev: Evaluation) -> np.ndarray | None:
    """The correlation of the frequency rows' known errors (None: independent, or none known)."""
    return None if ev.known is None else ev.known_corr


def _shape_sigma(ev: Evaluation) -> np.ndarray:
    f = frequency_rows(ev)
    return np.ones(int((~f).sum())) if ev.sigma is None else np.asarray(ev.sigma, float)[~f]


def _shape_known(ev: Evaluation) -> np.ndarray | None:
    """The known error of every shape row (the mesh's, relative to its mode's RMS); None: none known."""
    f = frequency_rows(ev)
    return None if ev.known is None or f.all() else np.asarray(ev.known, float)[~f]


def block_error(ev: Evaluation, data: list[StateData] | None, n_params: int, *, reference: str = "") -> ModelError:
    """The model error of one evaluation, each block on its own (:func:`estimate`): the frequency rows
    with their known errors and ``n_params`` fitted parameters, the shape rows (if any) with one best
    scale per measured shape.  The shape block is :attr:`ModelError.shape`."""
    f = frequency_rows(ev)
    me = estimate(ev.r[f], row_sigma(ev, data), n_params, known_rel=row_known(ev), known_corr=row_known_corr(ev),
                  reference=reference)
    if f.all():
        return me
    shape = estimate(ev.r[~f], _shape_sigma(ev), ev.n_scales, known_rel=_shape_known(ev), reference=reference)
    return replace(me, shape=shape)


def chi2_at(ev: Evaluation, data: list[StateData], me: ModelError) -> float:
    """Chi-square at the total uncertainty of :class:`ModelError` ``me``: the frequency rows at their
    stated noise, known error and the model error, the shape rows at their shape noise plus the shape
    block's model error (``me.shape``; none: their noise alone)."""
    f = frequency_rows(ev)
    out = me.chi2_total(ev.r[f], row_sigma(ev, data), row_known(ev), row_known_corr(ev))
    if not f.all():
        rs = ev.r[~f]
        out += float(rs @ rs) if me.shape is None else me.shape.chi2_total(rs, _shape_sigma(ev), _shape_known(ev))
    return out


def whitener(ev: Evaluation, data: list[StateData] | None, me: ModelError) -> np.ndarray:
    """The matrix taking the evaluation's sigma-normalised rows to units of the total uncertainty of
    ``me`` (:meth:`ModelError.whitener`): the frequency block with its known errors and their
    correlation, the shape rows (diagonal) with ``me.shape``; ``A r`` has :func:`chi2_at` as its square
    and ``A J`` gives the parameters' information."""
    f = frequency_rows(ev)
    idx = np.flatnonzero(f)
    A = np.eye(len(ev.r))
    A[np.ix_(idx, idx)] = me.whitener(row_sigma(ev, data), row_known(ev), row_known_corr(ev))
    if not f.all() and me.shape is not None:
        rest = np.flatnonzero(~f)
        A[rest, rest] = np.sqrt(me.shape.row_weights(_shape_sigma(ev), _shape_known(ev)))
    return A


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

    def block_chi2(self, extra_params: int = 0) -> list[tuple[str, float, int]]:
        """Per block ``(name, chi-square at the stated noise, degrees of freedom)``: the frequency rows
        (the fitted parameters, and ``extra_params`` profiled outside ``x``, counted off them) and, where
        shapes are fitted, the shape rows (their best scales counted off)."""
        f = frequency_rows(self.ev)
        rf = self.ev.r[f]
        out = [("frequency", float(rf @ rf), max(int(f.sum()) - self.k - extra_params, 1))]
        if not f.all():
            rs = self.ev.r[~f]
            out.append(("shape", float(rs @ rs), max(int((~f).sum()) - self.ev.n_scales, 1)))
        return out

    def p_value_at(self, extra_params: int = 0) -> float:
        """The least of the blocks' chi-square p-values at the stated noise: the fit is consistent with
        the noise only when every block is (a block that fits well cannot hide one that does not)."""
        return min(chi2_p_value(c, d) for _, c, d in self.block_chi2(extra_params))

    @property
    def p_value(self) -> float:
        """Probability of a chi-square at least this large if the variant were true (noise only), the
        least over the blocks (:meth:`p_value_at`)."""
        return self.p_value_at()

    def own_error(self, extra_params: int = 0) -> ModelError:
        """The model error this fit leaves, each block from its own moment equation (:func:`block_error`)."""
        return block_error(self.ev, None, self.k + extra_params)

    @property
    def aicc(self) -> float:
        """Corrected Akaike criterion of the fit (sigma known), :func:`jointid.diagnosis.criteria.aicc`."""
        return aicc(self.chi2, self.n, self.k)

    def covariance(self) -> np.ndarray:
        """Covariance of ``x``: ``(J^T J)^+`` (residuals in units of sigma): right when the model fits
        within the noise; the reported intervals use :meth:`scaled_covariance`."""
        J = self.ev.J
        return np.linalg.pinv(J.T @ J)

    def interval_scale(self, extra_params: int = 0) -> float:
        """``max(1, sqrt(chi2 / dof))`` of the frequency rows: how much wider than the noise alone the
        frequency rows are taken.  A fit worse than the measurement uncertainty misses something the
        noise does not cover, and its local curvature then understates how far the parameters could
        move (in a flat valley far above the noise, by the same factor).  ``extra_params`` counts
        parameters chosen outside ``x`` (e.g. a profiled preload): they take degrees of freedom too."""
        _, chi2, dof = self.block_chi2(extra_params)[0]
        return max(1.0, math.sqrt(chi2 / dof))

    def scaled_covariance(self, extra_params: int = 0) -> np.ndarray:
        """``(J^T W J)^+``, each row weighted by its stated over its total variance (the noise, the
        known error and the model error the fit leaves in its block, :meth:`own_error`): the covariance
        every reported 95 % interval of the diagnosis comes from.  With one block, one noise and no
        known error this is :meth:`covariance` times :meth:`interval_scale` squared (the identification's
        and the hypotheses' rule); with shapes, each block is widened by its own model error."""
        if self.one_noise():
            return self.covariance() * self.interval_scale(extra_params) ** 2
        A = whitener(self.ev, None, self.own_error(extra_params))
        J = A @ self.ev.J
        cov = np.linalg.pinv(J.T @ J)
        if frequency_rows(self.ev).all():
            return cov
        return cov * self._cluster_factor(cov, A, extra_params)

    def _clusters(self) -> dict:
        """Row numbers of each measured mode of each state (its frequency and shape rows); a misfit row
        is a cluster of its own."""
        groups: dict = {}
        for k, (si, m) in enumerate(self.ev.rows):
            groups.setdefault((si, abs(m)) if m != 0 else (si, -1 - k), []).append(k)
        return groups

    def shape_design_effect(self) -> float:
        """How many times less evidence the shape rows carry than independent rows would: the mean, over
        the parameters the shapes are sensitive to, of the cluster-robust (one cluster per measured mode
        and state) over the weighted variance from the shape rows alone; at least 1 (1 without shapes)."""
        f = frequency_rows(self.ev)
        if f.all():
            return 1.0
        w = np.zeros(len(self.ev.r))
        w[~f] = self.own_error().shape.row_weights(_shape_sigma(self.ev), _shape_known(self.ev))
        J = self.ev.J
        norms = np.linalg.norm(J[~f], axis=0)
        use = norms > 1e-6 * norms.max() if norms.max() > 0 else np.zeros(len(norms), bool)
        groups = [g for g in self._clusters().values() if not f[g[-1]]]
        G, p = len(groups), int(use.sum())
        if not use.any() or G <= p:
            return 1.0
        Js = J[:, use] * np.sqrt(w)[:, None]
        cov = np.linalg.pinv(Js.T @ Js)
        wr = w * self.ev.r
        U = np.array([J[g][:, use].T @ wr[g] for g in groups])
        robust = cov @ (U.T @ U * G / (G - p)) @ cov
        d = np.diag(cov)
        ok = d > 0
        return float(max(1.0, np.mean(np.diag(robust)[ok] / d[ok]))) if ok.any() else 1.0

    def _cluster_factor(self, cov: np.ndarray, A: np.ndarray, extra_params: int) -> float:
        """How much wider the cluster-robust (sandwich) variances are than ``cov``, at least 1.

        A model error of a mode shape is not noise: it moves all the mode's displacements together, so
        its rows are not independent.  With every measured mode of a state a cluster (its frequency row
        and its shape rows; a misfit row a cluster of its own), the sandwich ``cov M cov`` with
        ``M = G/(G - p) sum_g u_g u_g^T``, ``u_g = J_g^T W_g r_g`` (Liang and Zeger 1986), allows any
        correlation inside a mode.  The intervals take the larger of the two: the whole covariance is
        scaled by the largest ratio of the sandwich's variance to ``cov``'s."""
        Jw, rw = A @ self.ev.J, A @ self.ev.r  # whitened rows (the known errors' correlation mixes only
        # frequency rows of one mode across states, which the clusters keep apart; an approximation there)
        return cluster_factor(cov, Jw, rw, self._clusters().values(), self.k + extra_params)

    def one_noise(self) -> bool:
        """One block (no shape rows), one stated noise and no known error."""
        ev = self.ev
        if not frequency_rows(ev).all() or (ev.known is not None and np.any(ev.known)):
            return False
        return ev.sigma is None or bool(np.all(np.asarray(ev.sigma) == ev.sigma[0]))

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


def standard_distance(fit, x) -> float:
    """The largest distance of ``x`` from the first ``len(x)`` parameters of ``fit``, in that fit's standard
    errors (its scaled covariance, the intervals every report gives)."""
    x = np.asarray(x, float)
    se = np.sqrt(np.maximum(np.diag(fit.scaled_covariance())[:len(x)], 0.0))
    d = np.abs(x - np.asarray(fit.x[:len(x)], float))
    return float(np.max(np.where(d > 0, d / np.maximum(se, 1e-300), 0.0), initial=0.0))


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
    p_value = f.p_value_at(extra_params)
    return {"delta_aicc": aicc(f.chi2, f.n, k) - current.aicc, "fit_chi2": f.chi2, "fit_p_value": p_value,
            "fit_n_data": f.n, "fit_n_params": k,
            "explains": bool(p_value >= alpha), "estimate": p0.from_t(t), "ci95_low": vals[0],
            "ci95_high": vals[1], "interval_scale": f.interval_scale(extra_params),
            "max_abs_error_pct_after": max(s["max_abs_error_pct"] for s in summ) if summ else np.nan,
            "rms_error_pct_after": float(np.sqrt(np.mean([s["rms_error_pct"] ** 2 for s in summ]))) if summ else np.nan}
