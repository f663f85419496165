"""Which physical effect does the model lack?  Calibration, score tests, refits, AICc, drift.

Numerics (see ``docs/effects.md`` and ``shared/design/PHYSICS.md``)
------------------------------------------------------------------
* Every model variant is affine in its term coefficients (``jointid.diagnosis.effects``).  Eigen-solutions come
  from :class:`ReducedSolver`, a Rayleigh-Ritz solver on a growing subspace of the full FE space: the
  exact modes at a reference point plus the first-order responses ``A^-1 (dK - lambda dM) phi`` to
  every parameter direction; at each new point the residuals ``K phi - lambda M phi`` of the Ritz
  pairs are checked in the full space and, where the estimated eigenvalue error exceeds ``tol``, the
  preconditioned residuals are added to the subspace (Davidson step with the reference
  factorisation, or a factorisation and Lanczos solve at a distant point).  The answers are therefore
  full-FE answers to ``tol`` (1e-6 relative eigenvalue error by default), at
  the cost of a few dense ``r x r`` eigen-problems; each fitted variant is finally checked against the
  full model (:meth:`ReducedSolver.verify`: a Sturm count confirms that no mode is missing below the
  refined Ritz pairs, else a full Lanczos solve).
* Sensitivities are exact for the (converged) subspace: ``dlambda_i/dx = y_i^T (dK - lambda_i dM) y_i``.
* Residual of mode i: ``r_i = ln(f_model / f_meas) / sigma`` (= relative error / sigma to first order),
  sigma the relative frequency uncertainty (dataset ``frequency_uncertainty_pct``, else
  ``identify.frequency_uncertainty_pct``); log residuals make the sensitivities of one model identical
  in every state, so between-state contrasts of a state-independent model vanish exactly.
* Score (Lagrange-multiplier) test of a candidate with parameters t at t = 0 (effect absent):
  ``P = I - J_x J_x^+``, ``LM = r^T P J_t (J_t^T P J_t)^+ J_t^T P r`` ~ chi2(q); one-sided for a
  parameter whose null sits on its bound (mass >= 0, compliance >= 0, beta >= 0): p = 0.5 chi2_1 sf,
  and a linearised estimate of the wrong sign explains nothing.  Explained fraction ``LM / r^T r``.
* Refits by bounded least squares (trust region) with several starts; ``AICc = chi2 + 2k +
  2k(k+1)/(n-k-1)`` (sigma known).  A variant "explains" the data when its chi2 is consistent with
  the noise (p >= ``alpha``, default 0.01).
"""

from __future__ import annotations

import math
import os
import sys
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import least_squares, linear_sum_assignment
from scipy.stats import chi2 as chi2_dist

from jointid.correlate import pairing as correlate
from jointid.correlate.mac import mac
from jointid.diagnosis.effects import (EFFECTS, Effect, StateInfo, System, apply_effects, baseline_coefficients,
                      build_system, enabled_effects)
from jointid.threads import limit_threads  # noqa: F401  (re-used by the command line)
from jointid.errors import DataError, NumericalWarning
from jointid.fe.reduced import ReducedSolver, Solution, pad_to_basis  # noqa: F401  (re-exported)

TWO_PI = 2.0 * np.pi
UNPAIRED_ERROR = 0.10  # a measured mode without a model partner counts as a 10 % frequency error
# a Jacobian column that a projection shrinks below this fraction of its norm is round-off (the
# reduced solver's eigenvalues are accurate to 1e-6; a real between-state sensitivity is O(1))
NEGLIGIBLE = 1e-4


def _log(msg: str) -> None:
    print(msg, flush=True)


# ====================================================================== data and variants
@dataclass
class StateData:
    """Measured data of one state: frequencies (Hz), optional shapes at the probe labels."""

    name: str
    info: StateInfo
    f_meas: np.ndarray
    shapes: np.ndarray | None
    sigma_rel: float


def dataset_states(ds, system: System, cfg: dict, states: list[str] | None = None) -> list[StateData]:
    """:class:`StateData` of the requested states of a :class:`jointid.data.dataset.Dataset`.

    The motor force comes from the dataset's ``conditions.yaml`` (the measured input), else from
    ``cfg['states']``.  The frequency uncertainty is the dataset's ``frequency_uncertainty_pct``,
    else ``identify.frequency_uncertainty_pct``.
    """
    names = list(states or ds.states)
    missing = [s for s in names if s not in ds.states]
    if missing:
        raise DataError([f"{ds.name}: state {s!r} is not in the dataset — its states are "
                         f"{', '.join(ds.states)}" for s in missing])
    sigma = float(ds.conditions.get("frequency_uncertainty_pct",
                                    cfg.get("identify", {}).get("frequency_uncertainty_pct", 1.0))) / 100
    low = correlate.below_band(ds.name, {s: ds.freqs(s) for s in names},
                               float(cfg.get("solver", {}).get("min_freq_Hz", 0.0)))
    if low:
        raise DataError(low)
    out = []
    for s in names:
        cond = ds.state_conditions(s)
        force = cond.get("em_force_N", cfg.get("states", {}).get(s, {}).get("em_force_N", 0.0))
        shapes = None
        if ds.shapes is not None and s in set(ds.shapes["state"]):
            shapes = ds.shape_matrix(s, system.labels)
        out.append(StateData(s, StateInfo(s, float(force)), ds.freqs(s), shapes, sigma))
    return out


@dataclass
class EffectSpec:
    """An effect inside a variant: start/fixed values (physical), options, fitted parameter names."""

    effect: Effect
    values: dict
    options: dict
    free: list

    @classmethod
    def candidate(cls, effect: Effect, options: dict | None = None) -> "EffectSpec":
        return cls(effect, effect.null_values(), {**effect.options, **(options or {})},
                   [p.name for p in effect.params])


class Variant:
    """A model variant: the joint parameters (log, shared by all states) plus effects.

    The parameter vector is ``x = [ln theta_1 .. ln theta_p, t_1 .. t_q]`` with ``t`` the
    dimensionless test variables of the free effect parameters (``effects.Param``).
    """

    def __init__(self, system: System, cfg: dict, effects: list[EffectSpec] = (), name: str | None = None,
                 theta_fixed: dict | None = None):
        self.system, self.cfg = system, cfg
        jp = cfg["joints"]["parameters"]
        self.theta_fixed = dict(theta_fixed or {})
        self.joint_names = [n for n in jp if n not in self.theta_fixed]
        self.effects = list(effects)
        self.name = name or ("baseline" if not self.effects else
                             "baseline + " + " + ".join(e.effect.name for e in self.effects))
        self.labels = list(self.joint_names)
        lo = [math.log(jp[n]["lower"]) for n in self.joint_names]
        hi = [math.log(jp[n]["upper"]) for n in self.joint_names]
        self._slots = []
        for i, spec in enumerate(self.effects):
            for pname in spec.free:
                p = spec.effect.param(pname)
                self._slots.append((i, p))
                self.labels.append(f"{spec.effect.name}.{pname}")
                a, b = p.t_bounds
                lo.append(a)
                hi.append(b if math.isfinite(b) else 1e6)
        self.lower, self.upper = np.array(lo), np.array(hi)
        self.p = len(self.joint_names)

    @property
    def n_params(self) -> int:
        return len(self.labels)

    def x_start(self, theta: dict | None = None) -> np.ndarray:
        """Start vector: ``theta`` (N/m^3) or the geometric mean of the bounds; effect start values."""
        x = 0.5 * (self.lower + self.upper)
        for j, n in enumerate(self.joint_names):
            if theta and n in theta:
                x[j] = math.log(theta[n])
        for k, (i, p) in enumerate(self._slots):
            x[self.p + k] = p.to_t(self.effects[i].values[p.name])
        return np.clip(x, self.lower, self.upper)

    def unpack(self, x) -> tuple[dict, list[dict]]:
        theta = {n: math.exp(float(v)) for n, v in zip(self.joint_names, x[: self.p])}
        theta.update(self.theta_fixed)
        vals = [dict(s.values) for s in self.effects]
        for k, (i, p) in enumerate(self._slots):
            vals[i][p.name] = p.from_t(float(x[self.p + k]))
        return theta, vals

    def physical(self, x) -> dict:
        """Parameter values in physical units by label."""
        theta, vals = self.unpack(x)
        out = {n: theta[n] for n in self.joint_names}
        for k, (i, p) in enumerate(self._slots):
            out[self.labels[self.p + k]] = vals[i][p.name]
        return out

    def coefficients(self, x, state: StateInfo) -> tuple[dict, dict]:
        theta, vals = self.unpack(x)
        kc, mc = baseline_coefficients(self.system, self.cfg, theta)
        active = [(s.effect, v, s.options) for s, v in zip(self.effects, vals)]
        return apply_effects(self.system, kc, mc, state, active)

    def dcoefficients(self, x, state: StateInfo) -> list[tuple[dict, dict]]:
        """Derivatives of the coefficients with respect to each component of ``x`` (central FD)."""
        x = np.asarray(x, float)
        out = []
        for j in range(self.n_params):
            h = 1e-6 if j < self.p else self._slots[j - self.p][1].fd_step(x[j])
            xp, xm = x.copy(), x.copy()
            xp[j] += h
            xm[j] -= h
            kp, mp = self.coefficients(xp, state)
            km, mm = self.coefficients(xm, state)
            dk = {k: (kp.get(k, 0.0) - km.get(k, 0.0)) / (2 * h) for k in sorted(set(kp) | set(km))}
            dm = {k: (mp.get(k, 0.0) - mm.get(k, 0.0)) / (2 * h) for k in sorted(set(mp) | set(mm))}
            out.append(({k: v for k, v in dk.items() if v != 0.0}, {k: v for k, v in dm.items() if v != 0.0}))
        return out

    def extended(self, spec: EffectSpec) -> "Variant":
        """This variant plus one more effect (its parameters appended at the end of ``x``)."""
        return Variant(self.system, self.cfg, self.effects + [spec], theta_fixed=self.theta_fixed)


# ====================================================================== evaluation and fits
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


class Diagnoser:
    """Evaluates and fits variants of one system on one set of measured states."""

    def __init__(self, system: System, cfg: dict, data: list[StateData], *, n_modes: int | None = None,
                 tol: float = 1e-6, mac_threshold: float = 0.5, solver: ReducedSolver | None = None, log=_log):
        self.system, self.cfg, self.data = system, cfg, data
        s = cfg.get("solver", {})
        self.min_freq = float(s.get("min_freq_Hz", 100.0))
        m = max(len(d.f_meas) for d in data)
        self.n_modes = n_modes or m + 8
        self.mac_threshold = mac_threshold
        self.log = log
        self.solver: ReducedSolver | None = solver
        if solver is not None:
            if solver.system is not system:
                raise ValueError("the reduced solver belongs to another system")
        self._tol = tol
        self._shift = float(s.get("shift_Hz", -10.0))
        self._backend = s.get("backend", "auto")

    # ------------------------------------------------------------ engine
    def _ensure_solver(self, variant: Variant, x):
        if self.solver is not None:
            return
        t0 = time.time()
        ref = self.data[0].info
        kc, mc = variant.coefficients(x, ref)
        directions = []
        for dkc, dmc in _term_directions(self.system):
            directions.append((dkc, dmc))
        m = max(len(d.f_meas) for d in self.data)
        self.solver = ReducedSolver(self.system, kc, mc, self.n_modes, directions, shift_Hz=self._shift,
                                    backend=self._backend, tol=self._tol, n_seed=m + 2)
        self.log(f"diagnosis: reduced solver with {self.solver.V.shape[1]} vectors "
                 f"({self.system.n_dofs} DOFs) in {time.time() - t0:.1f} s")

    def solve_states(self, variant: Variant, x, refine: bool = True) -> list[Solution]:
        """Modes of every state at ``x`` (refined to the solver tolerance unless ``refine`` is False)."""
        self._ensure_solver(variant, x)
        for _ in range(3):
            gen = self.solver.generation
            sols = [self.solver.solve(*variant.coefficients(x, d.info), self.n_modes, refine=refine)
                    for d in self.data]
            if self.solver.generation == gen:
                return sols
        return sols

    def pair(self, sols: list[Solution]) -> list[correlate.Pairing]:
        """Pair measured and model modes per state: by MAC where shapes are measured; frequency-only
        states with equal mode counts are paired jointly with one mode identity across states."""
        freq_only = [k for k, d in enumerate(self.data) if d.shapes is None]
        out: list = [None] * len(self.data)
        if len(freq_only) >= 2 and len({len(self.data[k].f_meas) for k in freq_only}) == 1:
            ref = sols[freq_only[0]]
            tracks = [self._track_model(ref, sols[k]) for k in freq_only]
            pairs = correlate.pair_states_by_frequency([self.data[k].f_meas for k in freq_only],
                                                       [sols[k].freqs_Hz for k in freq_only], tracks,
                                                       min_freq_Hz=self.min_freq)
            for k, p in zip(freq_only, pairs):
                out[k] = p
        for k, (d, s) in enumerate(zip(self.data, sols)):
            if out[k] is None:
                out[k] = correlate.pair_modes(d.f_meas, s.freqs_Hz, d.shapes,
                                              s.shapes if d.shapes is not None else None,
                                              threshold=self.mac_threshold, min_freq_Hz=self.min_freq)
        return out

    def _track_model(self, ref: Solution, sol: Solution) -> np.ndarray:
        """Model mode of ``sol`` continuing each mode of ``ref`` (reduced-space MAC, -1 below 0.5)."""
        r = self.solver.V.shape[1]
        A, B = pad_to_basis(ref.Y, r), pad_to_basis(sol.Y, r)
        C = (A.T @ B) ** 2 / np.outer((A * A).sum(0), (B * B).sum(0))
        rr, cc = linear_sum_assignment(-C)
        out = -np.ones(A.shape[1], dtype=int)
        good = C[rr, cc] >= 0.5
        out[rr[good]] = cc[good]
        return out

    def evaluate(self, variant: Variant, x, index: list, track: list | None = None, *,
                 refine: bool = True) -> Evaluation:
        """Residuals ``ln(f_model / f_meas) / sigma`` and Jacobian at ``x``.

        ``index`` gives the model mode of each measured mode; with ``track`` (reference reduced
        vectors per state, columns = measured modes) each measured mode follows the model mode of
        largest mass-weighted MAC instead (mode crossings during a fit).
        """
        x = np.asarray(x, float)
        sols = self.solve_states(variant, x, refine=refine)
        r, J, rows, new_index, fmod = [], [], [], [], []
        for si, (d, sol) in enumerate(zip(self.data, sols)):
            idx = np.array(index[si])
            if track is not None and track[si] is not None:
                idx = self._follow(sol, track[si], idx)
            new_index.append(idx)
            ok = np.flatnonzero(idx >= 0)
            bad = np.flatnonzero(idx < 0)
            f = sol.freqs_Hz[idx[ok]]
            fm = d.f_meas[ok]
            r.append(np.log(f / fm) / d.sigma_rel)
            r.append(np.full(len(bad), np.log1p(UNPAIRED_ERROR) / d.sigma_rel))
            fm_all = np.full(len(d.f_meas), np.nan)
            fm_all[ok] = f
            fmod.append(fm_all)
            dc = variant.dcoefficients(x, d.info)
            Jb = np.zeros((len(ok) + len(bad), variant.n_params))
            sub = Solution(sol.freqs_Hz[idx[ok]], sol.lam[idx[ok]], sol.Y[:, idx[ok]], sol.lam_all, sol.Y_all,
                           sol.kc, sol.mc, sol.shapes[:, idx[ok]], sol.generation)
            for j, (dkc, dmc) in enumerate(dc):
                dlam = self.solver.sensitivity(sub, dkc, dmc)
                Jb[: len(ok), j] = dlam / (2 * np.maximum(sub.lam, 1e-9)) / d.sigma_rel
            J.append(Jb)
            rows += [(si, int(i) + 1) for i in ok] + [(si, int(i) + 1) for i in bad]
        return Evaluation(x, np.concatenate(r), np.vstack(J), sols, new_index, rows, fmod)

    def _follow(self, sol: Solution, ref_Y: np.ndarray, idx: np.ndarray) -> np.ndarray:
        r = self.solver.V.shape[1]
        Yr = pad_to_basis(ref_Y, r)
        Y = pad_to_basis(sol.Y, r)
        # the basis is M_ref-orthonormal: the reduced Euclidean product approximates the mass product
        C = (Yr.T @ Y) ** 2 / np.outer((Yr * Yr).sum(0), (Y * Y).sum(0))
        out = idx.copy()
        rows = np.flatnonzero(idx >= 0)
        if len(rows):
            rr, cc = linear_sum_assignment(-C[rows])
            out[rows[rr]] = cc
        return out

    def fit(self, variant: Variant, x0, *, index=None, max_loops: int = 4, verify: bool = False) -> "Fit":
        """Bounded least squares of ``variant`` from ``x0``; pairing re-done until stable."""
        x0 = np.clip(np.asarray(x0, float), variant.lower, variant.upper)
        if index is None:
            index = [p.model_index for p in self.pair(self.solve_states(variant, x0))]
        ev = None
        for loop in range(max_loops + 3):
            sols = self.solve_states(variant, x0)
            track = [s.Y[:, np.clip(ix, 0, None)] for s, ix in zip(sols, index)]
            cache = {}

            def ev_at(x):
                key = np.asarray(x, float).tobytes()
                if key not in cache:
                    cache.clear()
                    cache[key] = self.evaluate(variant, x, index, track, refine=False)
                return cache[key]

            if variant.n_params:
                # least squares on the current subspace, then refinement at the optimum; repeated
                # while the refinement changes the subspace (the optimum was not yet exact)
                res = least_squares(lambda x: ev_at(x).r, x0, jac=lambda x: ev_at(x).J,
                                    bounds=(variant.lower, variant.upper), method="trf", x_scale=1.0,
                                    xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=40)
                x_opt = res.x
            else:
                x_opt = x0
            size = (self.solver.generation, self.solver.V.shape[1])
            ev = self.evaluate(variant, x_opt, index, track, refine=True)
            changed_space = (self.solver.generation, self.solver.V.shape[1]) != size
            new = [p.model_index for p in self.pair(ev.solutions)]
            same_pairs = all(np.array_equal(a, b) for a, b in zip(new, ev.index))
            if not same_pairs:
                index = new
            x0 = x_opt
            if same_pairs and (not changed_space or not variant.n_params):
                break
        if verify:
            coeffs = []
            for d in self.data:  # states with identical coefficients need one check only
                c = variant.coefficients(ev.x, d.info)
                if c not in coeffs:
                    coeffs.append(c)
            worst = max(self.solver.verify(kc, mc, self.n_modes) for kc, mc in coeffs)
            if worst > 1e-5:
                self.log(f"diagnosis: reduced vs full FE {worst:.2e} at the optimum of {variant.name}; refitting")
                return self.fit(variant, ev.x, index=ev.index, max_loops=2, verify=False)
        return Fit(variant, ev, self.pair(ev.solutions))


@dataclass
class Fit:
    """A fitted variant: parameters, residuals, chi-square, AICc, covariance, per-state errors."""

    variant: Variant
    ev: Evaluation
    pairings: list

    @property
    def x(self):
        return self.ev.x

    @property
    def chi2(self) -> float:
        return float(self.ev.r @ self.ev.r)

    @property
    def n(self) -> int:
        return len(self.ev.r)

    @property
    def k(self) -> int:
        return self.variant.n_params

    @property
    def dof(self) -> int:
        return max(self.n - self.k, 1)

    @property
    def p_value(self) -> float:
        """Probability of a chi-square at least this large if the variant were true (noise only)."""
        return float(chi2_dist.sf(self.chi2, self.dof))

    @property
    def aicc(self) -> float:
        n, k = self.n, self.k
        corr = 2 * k * (k + 1) / (n - k - 1) if n - k - 1 > 0 else math.inf
        return self.chi2 + 2 * k + corr

    def covariance(self) -> np.ndarray:
        J = self.ev.J
        return np.linalg.pinv(J.T @ J)

    def errors_pct(self, data: list[StateData]) -> list[np.ndarray]:
        return [100 * (fm - d.f_meas) / d.f_meas for fm, d in zip(self.ev.f_model, data)]

    def state_summary(self, data: list[StateData]) -> list[dict]:
        out = []
        for d, e in zip(data, self.errors_pct(data)):
            e = e[np.isfinite(e)]
            out.append({"state": d.name, "n_paired": len(e),
                        "max_abs_error_pct": float(np.abs(e).max()) if len(e) else np.nan,
                        "rms_error_pct": float(np.sqrt(np.mean(e ** 2))) if len(e) else np.nan})
        return out


def _term_directions(system: System) -> list[tuple[dict, dict]]:
    """Seed directions of the reduced solver: the joint layers of all carriages per direction, the
    rail fixing, the foundation, the mounts and each added-mass layer (per-carriage detail is
    added by the refinement when a point needs it)."""
    groups = {}
    for name in system.stiffness:
        if "@" in name:
            d = name.split("@")[0].split("_")[2]
            groups.setdefault(d, {})[name] = 1.0
    out = [(g, {}) for g in groups.values()]
    for name in ("K_railfix", "K_foundation", "K_mount"):
        if name in system.stiffness:
            out.append(({name: 1.0}, {}))
    for name in system.mass:
        if name != "M0":
            out.append(({}, {name: 1.0}))
    return out


# ====================================================================== score tests and refits
def extra_jacobian(diag: Diagnoser, variant: Variant, x, ev: Evaluation, cols) -> np.ndarray:
    """Jacobian columns ``cols`` of ``variant`` at ``x`` using the solutions and pairing of ``ev``."""
    out = []
    for si, (d, sol) in enumerate(zip(diag.data, ev.solutions)):
        idx = np.asarray(ev.index[si])
        ok = np.flatnonzero(idx >= 0)
        sub = Solution(sol.freqs_Hz[idx[ok]], sol.lam[idx[ok]], sol.Y[:, idx[ok]], sol.lam_all, sol.Y_all,
                       sol.kc, sol.mc, sol.shapes[:, idx[ok]], sol.generation)
        dc = variant.dcoefficients(x, d.info)
        f = sub.freqs_Hz
        fm = d.f_meas[ok]
        Jb = np.zeros((len(idx), len(cols)))
        for k, j in enumerate(cols):
            dlam = diag.solver.sensitivity(sub, *dc[j])
            Jb[: len(ok), k] = dlam / (2 * np.maximum(sub.lam, 1e-9)) / d.sigma_rel
        out.append(Jb)
    return np.vstack(out)


def score_test(r: np.ndarray, Jx: np.ndarray, Jt: np.ndarray, t_lower: np.ndarray, *,
               scale_x: np.ndarray | None = None, scale_t: np.ndarray | None = None) -> dict:
    """Lagrange-multiplier (score) test of extra parameters ``t`` at ``t = 0``.

    Parameters
    ----------
    r : (n,) sigma-normalised residuals of the fitted (restricted) model.
    Jx : (n, p) Jacobian of the fitted parameters.
    Jt : (n, q) Jacobian of the candidate's parameters at their null.
    t_lower : (q,) lower bounds of ``t`` (0 when the null is on the bound).
    scale_x, scale_t : (p,), (q,) optional
        Column norms of the Jacobians before a projection (e.g. onto between-state contrasts).  A
        column that the projection shrinks below ``NEGLIGIBLE`` of its norm is round-off (a
        parameter acting alike in every state has no between-state sensitivity) and is dropped:
        its direction would otherwise be arbitrary.

    Returns
    -------
    dict
        ``score`` (LM statistic), ``p_value``, ``explained_fraction``, ``t_hat`` (linearised estimate),
        ``sign_ok``, ``collinearity`` (norm of the projected over the raw sensitivity, 0 = fully
        explained by the fitted parameters).
    """
    n, q = Jt.shape
    if scale_x is not None:
        Jx = Jx[:, np.linalg.norm(Jx, axis=0) > NEGLIGIBLE * np.asarray(scale_x)]
    if scale_t is not None:
        Jt = np.where(np.linalg.norm(Jt, axis=0) > NEGLIGIBLE * np.asarray(scale_t), Jt, 0.0)
    if Jx.shape[1]:
        U, sv, _ = np.linalg.svd(Jx, full_matrices=False)
        Q = U[:, sv > 1e-10 * sv.max()] if sv.max() > 0 else U[:, :0]  # range of Jx (rank-revealing)
        PJ = Jt - Q @ (Q.T @ Jt)
    else:
        PJ = Jt
    raw = np.linalg.norm(Jt, axis=0)
    proj = np.linalg.norm(PJ, axis=0)
    coll = float(np.min(np.where(raw > 0, proj / np.where(raw > 0, raw, 1), 0.0))) if q else 0.0
    g = PJ.T @ r
    H = PJ.T @ PJ
    Hinv = np.linalg.pinv(H, rcond=1e-10)
    lm = float(g @ Hinv @ g)
    t_hat = -Hinv @ g
    rr = float(r @ r)
    sign_ok = bool(np.all(t_hat >= t_lower - 1e-12))
    if raw.max() == 0 or coll < 1e-6:
        lm = 0.0
    if q == 1 and t_lower[0] == 0.0:
        p = 0.5 * float(chi2_dist.sf(lm, 1)) if sign_ok else 1.0
    else:
        p = float(chi2_dist.sf(lm, q))
    explained = (lm / rr if rr > 0 else 0.0) if sign_ok else 0.0
    return {"score": lm if sign_ok else 0.0, "score_two_sided": lm, "p_value": p if lm > 0 else 1.0,
            "explained_fraction": float(min(explained, 1.0)), "t_hat": t_hat, "sign_ok": sign_ok,
            "collinearity": coll}


def state_contrasts(ev: "Evaluation", n_states: int) -> np.ndarray:
    """Orthonormal between-state contrasts ``C`` of the residual vector ``(n_c, n)``.

    For every measured mode number paired in all states, the residuals across the states are
    projected onto the complement of the all-ones vector (Helmert basis), so ``C r`` is the part of
    the residual that differs between states (unit variance per component, like ``r``).  Effects
    acting alike in every state (masses, supports) have no sensitivity there; only state-dependent
    effects can explain it.
    """
    if n_states < 2:
        return np.zeros((0, len(ev.r)))
    paired = {}
    for k, (si, mode) in enumerate(ev.rows):
        if ev.index[si][mode - 1] >= 0:
            paired.setdefault(mode, {})[si] = k
    H = np.zeros((n_states - 1, n_states))
    for j in range(1, n_states):
        H[j - 1, :j] = 1.0
        H[j - 1, j] = -j
        H[j - 1] /= np.linalg.norm(H[j - 1])
    rows = []
    for mode, by_state in sorted(paired.items()):
        if len(by_state) != n_states:
            continue
        for h in H:
            c = np.zeros(len(ev.r))
            for si, k in by_state.items():
                c[k] = h[si]
            rows.append(c)
    return np.array(rows) if rows else np.zeros((0, len(ev.r)))


def identifiability(J: np.ndarray, labels: list[str], threshold: float = 1e-3) -> dict:
    """SVD of the column-normalised Jacobian: condition and the weakest parameter combination."""
    if J.size == 0:
        return {"ratio": 1.0, "weak": "", "flag": False}
    norms = np.linalg.norm(J, axis=0)
    Jn = J / np.where(norms > 0, norms, 1.0)
    s, V = np.linalg.svd(Jn, full_matrices=False)[1:]
    ratio = float(s[-1] / s[0]) if s[0] > 0 else 0.0
    v = V[-1]
    parts = [f"{c:+.2f} {lab}" for c, lab in sorted(zip(v, labels), key=lambda t: -abs(t[0])) if abs(c) > 0.1]
    return {"ratio": ratio, "weak": " ".join(parts), "flag": bool(ratio < threshold or np.any(norms == 0))}


@dataclass
class Diagnosis:
    """Everything the diagnosis of one dataset found (tables are DataFrames)."""

    ranking: pd.DataFrame
    ladder: pd.DataFrame
    compare: pd.DataFrame
    compare_summary: pd.DataFrame
    current: pd.DataFrame
    drift: pd.DataFrame
    shape_residuals: pd.DataFrame
    point_residuals: pd.DataFrame
    mac: dict
    verdict: str
    explained_by: str
    fits: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    parameters: pd.DataFrame | None = None
    timing_s: float = 0.0
    solver: ReducedSolver | None = None


def _state_errors_table(diag: Diagnoser, fit: Fit, label: str) -> list[dict]:
    rows = []
    for s in fit.state_summary(diag.data):
        rows.append({"variant": label, **s, "chi2": fit.chi2, "n_data": fit.n, "n_params": fit.k,
                     "aicc": fit.aicc, "p_value": fit.p_value})
    return rows


def _refit_starts(spec: EffectSpec, t_hat: float) -> list[float]:
    """Start values of a one-parameter candidate: its linearised estimate and a bracket above it
    (effects saturate, so the linearised estimate tends to be low), inside the bounds."""
    p = spec.effect.params[0]
    lo, hi = p.t_bounds
    hi = hi if math.isfinite(hi) else 1e6
    span = hi - lo
    base = float(np.clip(t_hat, lo + 1e-3 * span, hi))
    out = [base]
    for s in (3.0 * base, lo + 0.3 * span):
        s = float(np.clip(s, lo + 1e-3 * span, hi))
        if all(abs(s - o) > 0.05 * max(abs(o), 1e-3 * span) for o in out):
            out.append(s)
        if len(out) == 2:
            break
    return out


def refit(diag: Diagnoser, fit: Fit, spec: EffectSpec, t_hat: np.ndarray, *, verify: bool = True) -> Fit:
    """Fit ``fit.variant + spec`` from several starts of the new parameters; best by chi-square."""
    var = fit.variant.extended(spec)
    q = var.n_params - fit.variant.n_params
    best = None
    starts = _refit_starts(spec, float(t_hat[0])) if q == 1 else [list(np.clip(t_hat, 0, None))]
    for s in starts:
        x0 = np.concatenate([fit.x, np.atleast_1d(s)])
        f = diag.fit(var, x0, index=fit.ev.index)
        if best is None or f.chi2 < best.chi2 - 1e-9:
            best = f
    if verify:
        best = diag.fit(var, best.x, index=best.ev.index, verify=True)
    return best


def diagnose(system: System, cfg: dict, data: list[StateData], *, effects_cfg: dict | None = None,
             candidates: list[str] | None = None, n_refit: int = 5, alpha: float = 0.01,
             reference_state: str | None = None, solver: ReducedSolver | None = None,
             compare: bool = True, drift: bool = True, log=_log) -> Diagnosis:
    """Run the whole loop on measured states: compare, calibrate, score, refit, rank, ladder, drift.

    Parameters
    ----------
    system : System
    cfg : dict
        Validated configuration (joints, solver, identify ...).
    data : list of StateData
    effects_cfg : dict, optional
        Effects enabled in the model (the ``effects`` config section); default ``cfg['effects']``.
    candidates : list of str, optional
        Library effects to test (default: all not enabled).
    n_refit : int
        Number of leading candidates refitted.
    alpha : float
        Significance level: a variant explains the data when its chi-square p-value >= alpha.
    reference_state : str, optional
        State the baseline is calibrated on for the comparison step (default: the state with the
        smallest motor force, first in order).
    solver : ReducedSolver, optional
        A reduced solver of the same system to reuse (its subspace only grows; saves the set-up when
        several datasets of one rig are diagnosed).
    compare, drift : bool
        Run the comparison step (baseline calibrated on the reference state) and the per-state drift
        fits (both on by default).

    Returns
    -------
    Diagnosis
    """
    t_start = time.time()
    enabled = enabled_effects(cfg.get("effects") if effects_cfg is None else effects_cfg)
    diag = Diagnoser(system, cfg, data, solver=solver, log=log)
    notes = []
    base = Variant(system, cfg, [])
    n_obs = sum(len(d.f_meas) for d in data)
    if n_obs <= base.n_params:
        raise DataError(f"diagnosis: {n_obs} measured frequencies for {base.n_params} fitted parameters "
                        f"({', '.join(base.labels)}): a fit leaves no residual to test an effect with — "
                        "measure more modes or states, or fix parameters (joints.fixed)")
    # ---------------------------------------------------------------- 1. compare (reference state)
    ref = reference_state or min(data, key=lambda d: d.info.em_force_N).name
    if compare and sum(len(d.f_meas) for d in data if d.name == ref) <= base.n_params:
        compare = False  # the reference state alone cannot determine the parameters
        notes.append(f"the comparison uses the baseline calibrated on all states: {ref} alone has no more "
                     f"measured modes than the {base.n_params} fitted parameters")
    x0 = base.x_start()
    diag._ensure_solver(base, x0)
    if compare:
        sub = Diagnoser(system, cfg, [d for d in data if d.name == ref], n_modes=diag.n_modes,
                        solver=diag.solver, log=log)
        log(f"diagnosis: calibrating the baseline on {ref}")
        fit_ref = sub.fit(base, x0)
        x0 = fit_ref.x
        compare_tab, mac_mats, shape_res = _compare_tables(diag, base, fit_ref.x)
    # ---------------------------------------------------------------- 2. ladder of configured variants
    log("diagnosis: calibrating the baseline on all states")
    fit_base = diag.fit(base, x0, verify=not enabled)
    if not compare:
        compare_tab, mac_mats, shape_res = _compare_tables(diag, base, fit_base.x)
    compare_summary = correlate.error_summary(compare_tab)
    ladder_rows = _state_errors_table(diag, fit_base, "baseline")
    fits = {"baseline": fit_base}
    current = fit_base
    for en in enabled:
        spec = EffectSpec(en.effect, dict(en.values), dict(en.options), [p.name for p in en.effect.params] if en.fit else [])
        var = current.variant.extended(spec)
        x0 = np.concatenate([current.x, [en.effect.param(n).to_t(en.values[n]) for n in spec.free]])
        log(f"diagnosis: calibrating {var.name}")
        current = diag.fit(var, x0, index=current.ev.index, verify=en is enabled[-1])
        label = "+" + en.effect.name
        fits[label] = current
        ladder_rows += _state_errors_table(diag, current, label)
    current_table = _compare_tables(diag, current.variant, current.x)[0]
    # ---------------------------------------------------------------- 3. score tests
    ev = diag.evaluate(current.variant, current.x, current.ev.index)
    current = Fit(current.variant, ev, current.pairings)
    in_model = {e.effect.name for e in enabled}
    names = [n for n in (list(EFFECTS) if candidates is None else candidates) if n not in in_model]
    C = state_contrasts(ev, len(data))
    rc = C @ ev.r if len(C) else np.zeros(0)
    between_share = float(rc @ rc / (ev.r @ ev.r)) if len(C) and ev.r @ ev.r > 0 else 0.0
    rows = []
    for name in names:
        eff = EFFECTS[name]
        spec = EffectSpec.candidate(eff, (effects_cfg or cfg.get("effects") or {}).get(name))
        why = eff.requires(system, cfg, [d.info for d in data], spec.options) if eff.requires else None
        row = {"effect": name, "title": eff.title, "parameter": eff.params[0].name, "unit": eff.params[0].unit}
        if why:
            row.update({"explained_fraction": 0.0, "score": 0.0, "p_value": 1.0, "note": f"not applicable: {why}"})
            rows.append((row, None, None))
            continue
        var = current.variant.extended(spec)
        x_ext = np.concatenate([current.x, np.zeros(var.n_params - current.variant.n_params)])
        cols = list(range(current.variant.n_params, var.n_params))
        Jt = extra_jacobian(diag, var, x_ext, ev, cols)
        lower = np.array([var.lower[c] for c in cols])
        st = score_test(ev.r, ev.J, Jt, lower)
        p0 = eff.params[0]
        row.update({"explained_fraction": st["explained_fraction"], "score": st["score"],
                    "p_value": st["p_value"], "linear_estimate": p0.from_t(float(st["t_hat"][0])),
                    "collinearity": st["collinearity"], "note": ""})
        if len(C):
            sd = score_test(C @ ev.r, C @ ev.J, C @ Jt, lower, scale_x=np.linalg.norm(ev.J, axis=0),
                            scale_t=np.linalg.norm(Jt, axis=0))
            row.update({"between_states_fraction": sd["explained_fraction"],
                        "between_states_p_value": sd["p_value"]})
        if st["collinearity"] < 1e-3:
            row["note"] = "collinear with the fitted parameters (cannot be told apart from them)"
        elif not st["sign_ok"]:
            row["note"] = "would need a value outside its physical range (wrong sign)"
        rows.append((row, spec, st))
    # ---------------------------------------------------------------- 4. refits
    order = sorted([r for r in rows if r[1] is not None and r[2]["sign_ok"] and r[0]["score"] > 0
                    and r[2]["collinearity"] >= 1e-3 and r[0]["explained_fraction"] >= 0.01],
                   key=lambda r: -r[0]["score"])
    for i, (row, spec, st) in enumerate(order[:n_refit]):
        log(f"diagnosis: refitting {current.variant.name} + {row['effect']}")
        f = refit(diag, current, spec, st["t_hat"], verify=i == 0)
        cov = f.covariance()
        j = f.variant.n_params - 1
        t, sd = float(f.x[j]), float(np.sqrt(max(cov[j, j], 0.0)))
        p0 = spec.effect.params[0]
        lo_t, hi_t = max(t - 1.96 * sd, p0.t_bounds[0]), t + 1.96 * sd
        vals = sorted([p0.from_t(lo_t) if lo_t != 0 else p0.null, p0.from_t(hi_t)])
        summ = f.state_summary(diag.data)
        row.update({"delta_aicc": f.aicc - current.aicc, "fit_chi2": f.chi2, "fit_p_value": f.p_value,
                    "explains": bool(f.p_value >= alpha), "estimate": p0.from_t(t), "ci95_low": vals[0],
                    "ci95_high": vals[1],
                    "max_abs_error_pct_after": max(s["max_abs_error_pct"] for s in summ),
                    "rms_error_pct_after": float(np.sqrt(np.mean([s["rms_error_pct"] ** 2 for s in summ])))})
        fits["+" + row["effect"]] = f
    ranking = _ranking_frame([r[0] for r in rows])
    # ---------------------------------------------------------------- 5. verdict and suggestion
    base_ok = current.p_value >= alpha
    explaining = ranking[ranking["explains"]]
    summ_cur = current.state_summary(diag.data)
    cur_txt = ", ".join(f"{s['state']} max {s['max_abs_error_pct']:.2f} % rms {s['rms_error_pct']:.2f} %" for s in summ_cur)
    if base_ok:
        verdict = (f"The current model ({current.variant.name}) explains the data within the noise "
                   f"(chi2 = {current.chi2:.1f} for {current.dof} degrees of freedom, p = {current.p_value:.2g}; "
                   f"{cur_txt}); no effect is missing.")
        explained_by = "none needed"
    elif len(explaining):
        best = explaining.iloc[0]
        verdict = (f"Missing effect: {best['effect']} ({best['title']}), {best['parameter']} = "
                   f"{best['estimate']:.4g} {best['unit']} (95 % CI {best['ci95_low']:.3g} .. {best['ci95_high']:.3g}). "
                   f"It explains {100 * best['explained_fraction']:.0f} % of the residual to first order; refitted, "
                   f"the error falls from max {max(s['max_abs_error_pct'] for s in summ_cur):.2f} % to "
                   f"{best['max_abs_error_pct_after']:.2f} % and chi2 is consistent with the noise "
                   f"(p = {best['fit_p_value']:.2g}, delta AICc = {best['delta_aicc']:.1f}). Enable it with "
                   f"effects: {{{best['effect']}: {{}}}} in config.yaml.")
        explained_by = str(best["effect"])
        ladder_rows += _state_errors_table(diag, fits["+" + best["effect"]], f"+{best['effect']} (suggested)")
    else:
        lead = ranking.iloc[0] if len(ranking) else None
        part = ""
        if lead is not None and lead.get("score", 0) > 0:
            part = (f" The closest candidate, {lead['effect']}, explains {100 * lead['explained_fraction']:.0f} % "
                    f"of the residual to first order")
            if isinstance(lead.get("fit_p_value"), float) and np.isfinite(lead.get("fit_p_value", np.nan)):
                part += (f" but leaves max {lead['max_abs_error_pct_after']:.2f} % error "
                         f"(refit p = {lead['fit_p_value']:.2g})")
            part += "."
        verdict = ("No listed effect explains the residual: the current model misses something outside the "
                   f"library ({cur_txt}; chi2 = {current.chi2:.1f} for {current.dof} degrees of freedom, "
                   f"p = {current.p_value:.2g})." + part)
        explained_by = "unexplained"
    if explained_by != "none needed" and between_share > 0.05 and ranking["between_states_fraction"].notna().any():
        b = ranking.sort_values("between_states_fraction", ascending=False, kind="stable").iloc[0]
        if b["between_states_fraction"] > 0.5:
            verdict += (f" Of the residual, {100 * between_share:.0f} % differs between the states; "
                        f"{b['effect']} explains {100 * b['between_states_fraction']:.0f} % of that "
                        f"between-state part (p = {b['between_states_p_value']:.2g}).")
        else:
            verdict += (f" Of the residual, {100 * between_share:.0f} % differs between the states; no listed "
                        "effect explains that between-state part.")
    # ---------------------------------------------------------------- 6. drift and identifiability
    drift_tab = _drift(diag, current, alpha, log) if drift else _drift(diag, current, alpha, log, skip=True)
    ident = identifiability(current.ev.J, current.variant.labels)
    if ident["flag"]:
        notes.append(f"weakly identifiable combination of the fitted parameters (sigma_min/sigma_max = "
                     f"{ident['ratio']:.1e}): {ident['weak']}")
    for d, p in zip(data, current.pairings):
        if p.unpaired_measured:
            notes.append(f"{d.name}: measured mode(s) {', '.join(str(i + 1) for i in p.unpaired_measured)} "
                         "have no model partner (listed in compare.csv)")
    params = _parameter_table(fits)
    sh = shape_res
    pr = correlate.point_residuals(sh) if len(sh) else correlate.point_residuals(sh)
    lad = pd.DataFrame(ladder_rows)
    return Diagnosis(ranking=ranking, ladder=lad, compare=compare_tab, compare_summary=compare_summary,
                     current=current_table, drift=drift_tab, shape_residuals=sh, point_residuals=pr, mac=mac_mats,
                     verdict=verdict, explained_by=explained_by, fits=fits, notes=notes, parameters=params,
                     timing_s=time.time() - t_start, solver=diag.solver)


def _ranking_frame(rows: list[dict]) -> pd.DataFrame:
    cols = ["rank", "effect", "explained_fraction", "score", "p_value", "delta_aicc", "explains", "parameter",
            "unit", "estimate", "ci95_low", "ci95_high", "linear_estimate", "fit_chi2", "fit_p_value",
            "max_abs_error_pct_after", "rms_error_pct_after", "between_states_fraction",
            "between_states_p_value", "collinearity", "title", "note"]
    df = pd.DataFrame(rows)
    for c in cols:
        if c not in df:
            df[c] = np.nan
    refitted = df["delta_aicc"].notna()
    a = df[refitted].sort_values(["explains", "delta_aicc"], ascending=[False, True], kind="stable")
    b = df[~refitted].sort_values("score", ascending=False, kind="stable")
    out = pd.concat([a, b], ignore_index=True)
    out["rank"] = np.arange(1, len(out) + 1)
    out["explains"] = out["explains"].astype(object).where(out["explains"].notna(), False).astype(bool)
    return out[cols]


def _parameter_table(fits: dict) -> pd.DataFrame:
    rows = []
    for label, f in fits.items():
        cov = f.covariance()
        for j, (lab, val) in enumerate(f.variant.physical(f.x).items()):
            sd = float(np.sqrt(max(cov[j, j], 0.0)))
            if j < f.variant.p:
                lo, hi = val * math.exp(-1.96 * sd), val * math.exp(1.96 * sd)
            else:
                p = f.variant._slots[j - f.variant.p][1]
                t = float(f.x[j])
                a, b = max(t - 1.96 * sd, p.t_bounds[0]), t + 1.96 * sd
                v = sorted([p.from_t(a) if a != 0 else p.null, p.from_t(b)])
                lo, hi = v
            rows.append({"variant": label, "parameter": lab, "value": val, "ci95_low": lo, "ci95_high": hi,
                         "on_bound": bool(min(f.x[j] - f.variant.lower[j], f.variant.upper[j] - f.x[j]) < 1e-6)})
    return pd.DataFrame(rows)


def _descriptions(diag: Diagnoser, sol: Solution) -> list[str] | None:
    """Plain-language description of each mode of ``sol`` (``jointid.fe.describe``)."""
    from jointid.fe.describe import describe_modes
    from jointid.fe.fem import Model

    sysm = diag.system
    m = sysm.model
    pseudo = Model(stiffness=sysm.stiffness, mass=sysm.mass, fixed=sysm.fixed, probe=sysm.probe,
                   doflocs=m.doflocs, dof_part=m.dof_part, meta=m.meta)
    try:
        return describe_modes(pseudo, diag.solver.full_phi(sol), sol.kc, sol.mc)["description"].tolist()
    except Exception as exc:  # descriptions are a convenience, never a reason to fail
        warnings.warn(f"mode descriptions unavailable ({exc})", NumericalWarning)
        return None


def _compare_tables(diag: Diagnoser, variant: Variant, x):
    """Per-mode errors (fresh pairing), MAC matrices and shape residuals of ``variant`` at ``x``."""
    sols = diag.solve_states(variant, x)
    pairings = diag.pair(sols)
    frames, macs, shapes = [], {}, []
    for d, s, p in zip(diag.data, sols, pairings):
        desc = _descriptions(diag, s)
        frames.append(correlate.frequency_errors(d.name, d.f_meas, s.freqs_Hz, p, desc))
        if d.shapes is not None:
            macs[d.name] = mac(d.shapes, s.shapes)
            shapes.append(correlate.shape_residuals(d.name, d.shapes, s.shapes, p, diag.system.labels))
    sh = pd.concat(shapes, ignore_index=True) if shapes else correlate.shape_residuals("", None, None, None, [])
    return pd.concat(frames, ignore_index=True), macs, sh


def _drift(diag: Diagnoser, current: Fit, alpha: float, log, skip: bool = False) -> pd.DataFrame:
    """Joint parameters fitted per state (effects fixed at their fitted values) and their drift."""
    if len(diag.data) < 2 or skip:
        return pd.DataFrame(columns=["parameter", "state", "value", "ci95_low", "ci95_high", "drift_pct", "z"])
    var = current.variant
    theta, vals = var.unpack(current.x)
    fixed_specs = [EffectSpec(s.effect, v, s.options, []) for s, v in zip(var.effects, vals)]
    one = Variant(diag.system, diag.cfg, fixed_specs, theta_fixed=var.theta_fixed)
    rows, ref = [], None
    for k, d in enumerate(diag.data):
        sub = Diagnoser(diag.system, diag.cfg, [d], n_modes=diag.n_modes, log=log)
        sub.solver = diag.solver
        if sum(np.asarray(current.ev.index[k]) >= 0) <= one.n_params:
            continue
        f = sub.fit(one, current.x[: one.n_params], index=[current.ev.index[k]])
        cov = f.covariance()
        for j, n in enumerate(one.joint_names):
            sd = float(np.sqrt(max(cov[j, j], 0.0)))
            rows.append({"parameter": n, "state": d.name, "value": math.exp(f.x[j]),
                         "ci95_low": math.exp(f.x[j] - 1.96 * sd), "ci95_high": math.exp(f.x[j] + 1.96 * sd),
                         "ln_value": float(f.x[j]), "ln_sd": sd})
    df = pd.DataFrame(rows)
    if df.empty:
        return pd.DataFrame(columns=["parameter", "state", "value", "ci95_low", "ci95_high", "drift_pct", "z"])
    out = []
    for n, g in df.groupby("parameter", sort=False):
        r0 = g.iloc[0]
        for _, r in g.iterrows():
            z = (r.ln_value - r0.ln_value) / math.sqrt(r.ln_sd ** 2 + r0.ln_sd ** 2) if r.name != r0.name else 0.0
            out.append({"parameter": n, "state": r.state, "value": r.value, "ci95_low": r.ci95_low,
                        "ci95_high": r.ci95_high, "drift_pct": 100 * (r.value / r0.value - 1), "z": z,
                        "significant": bool(abs(z) > 2.0)})
    return pd.DataFrame(out)


# ====================================================================== outputs
def _fig_png(fig) -> str:
    import base64
    import io as _io

    buf = _io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode()


def figures(res: Diagnosis) -> dict[str, str]:
    """Figures of the report as base64 PNG: ladder, per-mode errors, ranking, point residuals, MAC."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = {}
    lad = res.ladder
    if len(lad):
        states = list(dict.fromkeys(lad["state"]))
        variants = list(dict.fromkeys(lad["variant"]))
        fig, axes = plt.subplots(1, 2, figsize=(10, 3.4), sharey=False)
        for ax, col, title in zip(axes, ("max_abs_error_pct", "rms_error_pct"), ("max |error|", "RMS error")):
            for s in states:
                g = lad[lad.state == s].set_index("variant").reindex(variants)
                ax.plot(range(len(variants)), g[col], marker="o", label=s)
            ax.set_xticks(range(len(variants)))
            ax.set_xticklabels(variants, rotation=20, ha="right", fontsize=8)
            ax.set_ylabel(f"{title} (%)")
            ax.set_yscale("log")
            ax.grid(True, alpha=0.3)
            ax.set_title(f"model ladder: {title} per state")
        axes[0].legend(fontsize=8)
        out["ladder"] = _fig_png(fig)
    fig, ax = plt.subplots(figsize=(10, 3.4))
    for (label, df), mk in zip((("baseline calibrated on the reference state", res.compare),
                                ("current model, all states", res.current)), ("o", "s")):
        p = df[df.status == "paired"]
        for s, g in p.groupby("state", sort=False):
            ax.plot(g["freq_meas_Hz"], g["error_pct"], mk, label=f"{label}: {s}", alpha=0.8)
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xlabel("measured frequency (Hz)")
    ax.set_ylabel("(model - measured) / measured (%)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title("where the model fails: error per mode")
    out["errors"] = _fig_png(fig)
    if len(res.ranking):
        fig, ax = plt.subplots(figsize=(8, 0.4 * len(res.ranking) + 1))
        r = res.ranking.iloc[::-1]
        colors = ["tab:green" if e else "tab:gray" for e in r["explains"]]
        ax.barh(r["effect"], 100 * r["explained_fraction"].fillna(0), color=colors)
        ax.set_xlabel("share of the residual explained to first order (%)")
        ax.set_xlim(0, 100)
        ax.set_title("candidate effects (green: refit reaches the noise level)")
        out["ranking"] = _fig_png(fig)
    if len(res.point_residuals):
        pr = res.point_residuals.sort_values("point")
        fig, ax = plt.subplots(figsize=(10, 3))
        ax.bar(pr["point"], pr["rms_residual"], color="tab:orange")
        ax.set_ylabel("RMS shape residual (unit-norm shapes)")
        ax.tick_params(axis="x", rotation=90, labelsize=7)
        ax.set_title("where the shapes fail: residual per measuring point (baseline)")
        out["points"] = _fig_png(fig)
    for state, M in res.mac.items():
        fig, ax = plt.subplots(figsize=(4.5, 3.6))
        im = ax.imshow(M, vmin=0, vmax=1, cmap="viridis", aspect="auto")
        ax.set_xlabel("model mode")
        ax.set_ylabel("measured mode")
        ax.set_xticks(range(M.shape[1]))
        ax.set_xticklabels(range(1, M.shape[1] + 1), fontsize=6)
        ax.set_yticks(range(M.shape[0]))
        ax.set_yticklabels(range(1, M.shape[0] + 1), fontsize=6)
        fig.colorbar(im, ax=ax, label="MAC")
        ax.set_title(f"MAC, {state} (baseline)")
        out[f"mac_{state}"] = _fig_png(fig)
    return out


def _html_table(df: pd.DataFrame, max_rows: int = 200) -> str:
    if df is None or df.empty:
        return "<p><i>none</i></p>"
    return df.head(max_rows).to_html(index=False, float_format=lambda v: f"{v:.4g}", na_rep="", border=0,
                                     classes="t")


def html_page(res: Diagnosis, dataset: str, run: dict) -> str:
    """A readable, self-contained report page (figures embedded)."""
    import html as _h

    figs = figures(res)

    def img(key, alt):
        return f'<img alt="{alt}" src="data:image/png;base64,{figs[key]}">' if key in figs else ""

    lib = pd.DataFrame([{k: v for k, v in r.items() if k != "title"} for r in _effect_rows()])
    rank_cols = ["rank", "effect", "explained_fraction", "score", "p_value", "delta_aicc", "explains",
                 "parameter", "estimate", "ci95_low", "ci95_high", "unit", "max_abs_error_pct_after", "note"]
    notes = "".join(f"<li>{_h.escape(n)}</li>" for n in res.notes) or "<li>none</li>"
    mac_imgs = "".join(img(f"mac_{s}", f"MAC {s}") for s in res.mac)
    return f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>jointid diagnosis: {_h.escape(dataset)}</title>
<style>
body {{font-family: sans-serif; max-width: 1100px; margin: 2em auto; color: #222; line-height: 1.4}}
.verdict {{background: #eef5ff; border-left: 6px solid #3a7bd5; padding: 0.8em 1em; font-size: 1.05em}}
table.t {{border-collapse: collapse; font-size: 0.82em; margin: 0.5em 0}}
table.t td, table.t th {{border-bottom: 1px solid #ddd; padding: 2px 6px; text-align: right}}
table.t th {{background: #f4f4f4}}
img {{max-width: 100%}} h2 {{border-bottom: 1px solid #ccc; padding-bottom: 2px}}
</style></head><body>
<h1>Which effect does the model lack? &mdash; dataset <code>{_h.escape(dataset)}</code></h1>
<p class="verdict">{_h.escape(res.verdict)}</p>
<p>Run {_h.escape(run.get('time_utc', ''))}, config hash <code>{_h.escape(run.get('config_hash', ''))}</code>,
model {_h.escape(str(run.get('n_dofs', '')))} DOFs, {res.timing_s:.0f} s.</p>
<h2>1. Compare: baseline calibrated on the reference state</h2>
{_html_table(res.compare_summary)}
{img('errors', 'errors per mode')}
{_html_table(res.compare)}
{mac_imgs}
<h2>2. Where it fails</h2>
<p>Per-mode errors above and, where shapes are measured, the shape residual per measuring point
(model shape scaled onto the unit-norm measured shape):</p>
{img('points', 'shape residual per point')}
{_html_table(res.point_residuals.head(12))}
<h2>3. Which listed effect is missing</h2>
<p>Score (Lagrange-multiplier) test of each candidate at the calibrated model, its sensitivities
projected off the fitted parameters; the leading candidates refitted and compared by AICc. A
candidate <i>explains</i> the data when its refit leaves a chi-square consistent with the noise.</p>
{img('ranking', 'ranking')}
{_html_table(res.ranking[[c for c in rank_cols if c in res.ranking]])}
<h2>4. Model ladder: watch the error fall</h2>
{img('ladder', 'ladder')}
{_html_table(res.ladder)}
<h3>Fitted parameters</h3>
{_html_table(res.parameters)}
<h3>Parameter drift between states (each state fitted alone)</h3>
<p>A drift beyond the confidence intervals (|z| &gt; 2) is evidence of a state-dependent effect.</p>
{_html_table(res.drift)}
<h3>Notes</h3><ul>{notes}</ul>
<h2>Effect library</h2>
{_html_table(lib)}
<p>Enable an effect with one line in <code>config.yaml</code>, e.g.
<code>effects: {{em_preload: {{beta: 0.2}}}}</code>, and rerun <code>snakemake -j2</code>; see docs/effects.md.</p>
</body></html>
"""


def _effect_rows():
    from jointid.diagnosis.effects import effect_table

    return effect_table()


def history_row(res: Diagnosis, dataset: str, cfg_hash: str) -> dict:
    """One row of ``results/history.csv`` for this run (current model's errors)."""
    cur = res.current[res.current.status == "paired"]
    summ = correlate.error_summary(res.current)
    errs = "; ".join(f"{r.state}: max {r.max_abs_error_pct:.3f} % rms {r.rms_error_pct:.3f} %"
                     for r in summ.itertuples())
    variant = res.ladder["variant"].iloc[-1] if len(res.ladder) else "baseline"
    non_sugg = [v for v in dict.fromkeys(res.ladder["variant"]) if "suggested" not in v]
    variant = non_sugg[-1] if non_sugg else variant
    e = cur["error_pct"].to_numpy(float)
    return {"time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "config_hash": cfg_hash,
            "dataset": dataset, "variant": variant,
            "max_abs_error_pct": float(np.abs(e).max()) if len(e) else np.nan,
            "rms_error_pct": float(np.sqrt(np.mean(e ** 2))) if len(e) else np.nan,
            "errors": errs, "verdict": res.explained_by}


def append_history(path, row: dict) -> None:
    """Append ``row`` to the CSV ``path`` (header written once; an exclusive lock guards parallel runs)."""
    import csv
    import fcntl
    from pathlib import Path

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a+", newline="") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        fh.seek(0)
        first = fh.readline()
        header = first.strip().split(",") if first else list(row)
        fh.seek(0, 2)
        w = csv.DictWriter(fh, fieldnames=header, extrasaction="ignore", lineterminator="\n")
        if not first:
            w.writeheader()
        w.writerow(row)
        fcntl.flock(fh, fcntl.LOCK_UN)


def write_outputs(res: Diagnosis, out_dir, dataset: str, run: dict) -> None:
    """Write ranking.csv, ladder.csv, compare.csv, current.csv, parameters.csv, drift.csv,
    shape_residuals.csv, point_residuals.csv, mac_<state>.csv, verdict.json and index.html."""
    from pathlib import Path

    from jointid import io

    out = Path(out_dir)
    page = html_page(res, dataset, run)  # figures first: a failure there leaves no partial set behind
    io.write_csv(res.ranking, out / "ranking.csv")
    io.write_csv(res.ladder, out / "ladder.csv")
    io.write_csv(res.compare, out / "compare.csv")
    io.write_csv(res.current, out / "current.csv")
    io.write_csv(res.parameters if res.parameters is not None else pd.DataFrame(), out / "parameters.csv")
    io.write_csv(res.drift, out / "drift.csv")
    io.write_csv(res.shape_residuals, out / "shape_residuals.csv")
    io.write_csv(res.point_residuals, out / "point_residuals.csv")
    for state, M in res.mac.items():
        df = pd.DataFrame(M, columns=[f"model_{j + 1}" for j in range(M.shape[1])])
        df.insert(0, "measured_mode", np.arange(1, M.shape[0] + 1))
        io.write_csv(df, out / f"mac_{state}.csv")
    io.write_json(out / "verdict.json", {"dataset": dataset, "verdict": res.verdict, "explained_by": res.explained_by,
                                         "notes": res.notes, "run": run, "timing_s": res.timing_s})
    io.write_text(out / "index.html", page)


# ====================================================================== stage and command line
def run_diagnosis(cfg: dict, dataset_name: str, dataset_path: str, matrices: str | None, out_dir: str, *,
                  history_csv: str | None = None, model=None, log=_log) -> Diagnosis:
    """Workflow stage: diagnose one dataset and write ``out_dir`` (+ a row of ``history_csv``).

    ``cfg`` holds the sections ``rig, joints, solver, identify, effects, states`` and ``dataset``
    (the ``datasets.<name>`` entry: ``path``, ``states``); the model comes from ``matrices`` (the
    cached ``results/model/matrices.npz``) or ``model``.
    """
    from jointid.config import config_hash
    from jointid.data.dataset import read_dataset
    from jointid.fe.model import load_model

    limit_threads(1)
    model = model or load_model(matrices)
    system = build_system(model, cfg)
    ds = read_dataset(dataset_path, measuring_points=system.meta["points"])
    entry = cfg.get("dataset") or {}
    data = dataset_states(ds, system, cfg, entry.get("states"))
    res = diagnose(system, cfg, data, log=log)
    h = config_hash({k: v for k, v in cfg.items() if k != "dataset"})
    run = {"time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "config_hash": h,
           "n_dofs": system.n_dofs, "dataset_path": str(dataset_path), "states": [d.name for d in data]}
    write_outputs(res, out_dir, dataset_name, run)
    if history_csv:
        append_history(history_csv, history_row(res, dataset_name, h))
    log(res.verdict)
    return res


def _check_outputs(out_dir: str, history: str | None) -> None:
    """Fail before any computation when the outputs cannot be written."""
    from jointid.errors import ConfigError

    problems = []
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        problems.append(f"--out {out_dir}: is a file, not a folder — name a folder for the outputs")
    if history is not None and os.path.isdir(history):
        problems.append(f"--history {history}: is a folder — name a CSV file to append the run's row to")
    for path in filter(None, (out_dir, history)):
        probe = os.path.abspath(path)
        while not os.path.exists(probe):  # the nearest existing folder is where it gets created
            probe = os.path.dirname(probe)
        if not os.access(probe, os.W_OK):
            problems.append(f"{path}: {probe} is not writable")
    if problems:
        raise ConfigError(problems)


def main(argv: list[str] | None = None) -> int:
    """``python -m jointid.diagnosis.core --dataset DIR --out DIR [--config config.yaml ...] [--set k=v]``."""
    import argparse

    from jointid.config import load_config
    from jointid.errors import ConfigError, JointidError

    ap = argparse.ArgumentParser(prog="python -m jointid.diagnosis.core",
                                 description="Diagnose which listed physical effect the model lacks.")
    ap.add_argument("--dataset", required=True, help="dataset folder (measurement format)")
    ap.add_argument("--out", required=True, help="output folder (ranking.csv, ladder.csv, index.html ...)")
    ap.add_argument("--config", nargs="*", default=["config.yaml"], help="config files merged in order")
    ap.add_argument("--states", nargs="*", default=None, help="states to use (default all of the dataset)")
    ap.add_argument("--effects", default=None,
                    help="YAML mapping of enabled effects, e.g. '{em_preload: {beta: 0.2}}' (overrides config)")
    ap.add_argument("--matrices", default=None, help="cached model matrices (default: build from the config)")
    ap.add_argument("--history", default=None, help="CSV to append a run row to")
    args = ap.parse_args(argv)
    try:
        import yaml

        from jointid.data.synth import _base_config

        _check_outputs(args.out, args.history)
        for path in args.config:
            if not os.path.isfile(path):
                raise ConfigError(f"--config {path}: no such file")
        if args.matrices is not None and not os.path.isfile(args.matrices):
            raise ConfigError(f"--matrices {args.matrices}: no such file — the mesh rule writes "
                              "results/model/matrices.npz; or leave --matrices out to build the model")
        raw = _base_config(args.config)
        if args.effects is not None:
            try:
                raw["effects"] = yaml.safe_load(args.effects) or {}
            except yaml.YAMLError as exc:
                raise ConfigError(f"--effects: not valid YAML ({str(exc).splitlines()[0]}) — write a mapping "
                                  "such as '{em_preload: {beta: 0.2}}'") from None
        cfg = load_config(raw)
        cfg["dataset"] = {"path": args.dataset, "states": args.states}
        model = None
        if args.matrices is None:
            from jointid.fe.model import build_model

            model = build_model(cfg)
        name = args.dataset.rstrip("/").split("/")[-1]
        run_diagnosis(cfg, name, args.dataset, args.matrices, args.out, history_csv=args.history, model=model)
    except JointidError as exc:
        print(str(exc), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
