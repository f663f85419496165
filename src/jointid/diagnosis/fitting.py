"""Evaluating and fitting model variants on measured states (docs/effects.md).

* :class:`Diagnoser` — solves every state of a :class:`~jointid.diagnosis.variants.Variant` with the
  reduced solver (:class:`jointid.fe.reduced.ReducedSolver`), pairs measured and model modes, and
  returns residuals ``r_i = ln(f_model / f_meas) / sigma`` with their Jacobian (:class:`Evaluation`);
  :meth:`Diagnoser.fit` is the bounded least-squares fit (trust region), pairing re-done until stable.
* :class:`Fit` (in :mod:`jointid.diagnosis.results`) — a fitted variant: chi-square, p-value, AICc, covariance, per-state errors.
* :func:`refit` — a fitted variant plus one candidate effect, fitted from several starts.

Numerics
--------
* Every model variant is affine in its term coefficients (``jointid.diagnosis.effects``).  Eigen-solutions
  come from :class:`ReducedSolver`, a Rayleigh-Ritz solver on a growing subspace of the full FE space:
  the exact modes at a reference point plus the first-order responses ``A^-1 (dK - lambda dM) phi`` to
  every parameter direction; at each new point the residuals ``K phi - lambda M phi`` of the Ritz pairs
  are checked in the full space and, where the estimated eigenvalue error exceeds ``tol``, the
  preconditioned residuals are added to the subspace.  The answers are therefore full-FE answers to
  ``tol`` (1e-6 relative eigenvalue error by default); each fitted variant is finally checked against
  the full model (:meth:`ReducedSolver.verify`).
* Sensitivities are exact for the (converged) subspace: ``dlambda_i/dx = y_i^T (dK - lambda_i dM) y_i``.
* Residual of mode i: ``r_i = ln(f_model / f_meas) / sigma`` (= relative error / sigma to first order),
  sigma the relative frequency uncertainty (dataset ``frequency_uncertainty_pct``, else
  ``identify.frequency_uncertainty_pct``); log residuals make the sensitivities of one model identical
  in every state, so between-state contrasts of a state-independent model vanish exactly.
* Refits by bounded least squares (trust region) with several starts.
* Where shapes are measured, shape rows follow the frequency rows (:mod:`jointid.diagnosis.shape_residuals`).
"""

from __future__ import annotations

import time

import numpy as np
from scipy.optimize import least_squares, linear_sum_assignment

from jointid.config.typed_diagnosis import DiagnosisSettings
from jointid.correlate import pairing as correlate
from jointid.diagnosis import mesh_error
from jointid.diagnosis.results import Evaluation, Fit, standard_distance
from jointid.diagnosis.shape_residuals import ShapeTerms
from jointid.diagnosis.starts import (EIGEN_RTOL, START_DIGITS, TIE_RTOL, best_fit, chi2_resolution,  # noqa: F401
                                      at_its_null, refit_starts, rounded_start, sized_starts)
from jointid.diagnosis.terms import System, term_component
from jointid.fe.solids import is_solid_term
from jointid.diagnosis.variants import EffectSpec, StateData, Variant
from jointid.fe.reduced import ReducedSolver, Solution, pad_to_basis
from jointid.identification.model_error import known_budget, mode_correlation
from jointid.progress import stamp

UNPAIRED_ERROR = 0.10  # a measured mode without a model partner counts as a 10 % frequency error


def print_log(msg: str) -> None:
    """Default progress log of the diagnosis: print with the wall-clock time, and flush."""
    print(stamp(msg), flush=True)


class Diagnoser:
    """Evaluates and fits variants of one system on one set of measured states."""

    def __init__(self, system: System, settings: DiagnosisSettings, data: list[StateData], *, n_modes: int | None = None,
                 tol: float = 1e-6, mac_threshold: float = 0.5, solver: ReducedSolver | None = None,
                 start_basis=None, memo=None, log=print_log):
        # many parameters: the fit's solver options beside system, configuration and data, keyword with defaults
        self.system, self.settings, self.data = system, settings, data
        self.min_freq = settings.min_freq_Hz
        m = max(len(d.f_meas) for d in data)
        self.n_modes = n_modes or m + 8
        self.mac_threshold, self.log = mac_threshold, log
        self.solver: ReducedSolver | None = solver
        if solver is not None and not shares_terms(solver.system, system):
            raise ValueError("the reduced solver belongs to another system")
        self._tol = tol
        self._shift = settings.shift_Hz
        self._backend = settings.backend
        self.start_basis = start_basis  # a basis kept from an earlier run (jointid.fe.warmstart)
        self.memo = memo  # fits remembered from an earlier run (jointid.diagnosis.memo.FitMemo)
        self.shapes = ShapeTerms(settings.shape_residuals, data)  # shape rows where shapes are measured (diagnosis.shape_residuals)
        self._context = None

    def context_digest(self) -> str:
        """Digest of what every fit of this diagnoser depends on (:meth:`FitMemo.context`), at the data
        as they are now."""
        return self.memo.context(self.settings, self.data, self.n_modes, self._tol, self.mac_threshold)

    def remembered(self, name: str, parts: tuple, compute, encode, decode, *, said: str | None = None):
        """``compute()``, or the value recorded for ``(name, *parts)`` in this diagnoser's context by an
        earlier run (:meth:`FitMemo.value_key`; ``decode`` turns the record back into the value, ``said``
        is logged then).  A value computed is recorded as ``encode(value)`` (JSON-ready, exact); None is
        not recorded.  Without a memo: ``compute()``."""
        if self.memo is None:
            return compute()
        key = self.memo.value_key(self.context_digest(), name, *parts)
        rec = self.memo.get_value(key)
        if rec is not None:
            if said:
                self.log(said)
            return decode(rec)
        value = compute()
        if value is not None:
            self.memo.put_value(key, encode(value))
        return value

    def reset_context(self) -> None:
        """Forget the memo's context digest: the states changed (a new mesh correction), so a fit recorded
        before is not the same fit."""
        self._context = None

    # ------------------------------------------------------------ engine
    def ensure_solver(self, variant: Variant, x):
        """Set up the reduced solver at ``x`` of ``variant`` (first state's coefficients) unless there is one."""
        if self.solver is not None:
            return
        t0 = time.time()
        ref = self.data[0].info
        kc, mc = variant.coefficients(x, ref)
        directions = []
        for dkc, dmc in term_directions(self.system):
            directions.append((dkc, dmc))
        m = max(len(d.f_meas) for d in self.data)
        self.solver = ReducedSolver(self.system, kc, mc, self.n_modes, directions, shift_Hz=self._shift,
                                    backend=self._backend, tol=self._tol, n_seed=m + 2, basis=self.start_basis,
                                    prefactor=True,  # every diagnosis checks points in the full space
                                    # a rerun with records of its fits checks few points (fe.reduced.CHECKS_BEFORE_PRODUCTS)
                                    defer_products=self.memo is not None and bool(self.memo.records))
        kept, self.start_basis = self.start_basis, None  # taken over by the solver
        self.solver.log = self.log
        kept = " (started from a kept basis)" if kept is not None else ""
        self.log(f"diagnosis: reduced solver with {self.solver.V.shape[1]} vectors{kept} "
                 f"({self.system.n_dofs} DOFs) in {time.time() - t0:.1f} s")

    def solve_states(self, variant: Variant, x, refine: bool = True) -> list[Solution]:
        """Modes of every state at ``x`` (refined to the solver tolerance unless ``refine`` is False)."""
        self.ensure_solver(variant, x)
        for _ in range(3):
            gen = self.solver.generation
            sols = self.solver.solve_many([variant.coefficients(x, d.info) for d in self.data], self.n_modes,
                                          refine=refine)
            if self.solver.generation == gen:
                break
        # the mesh's correction, where the budget has one (jointid.diagnosis.mesh_error), follows each model mode
        return [mesh_error.correct(d, s, lambda cols, s=s: mesh_error.solid_share(self.solver, s, cols))
                for d, s in zip(self.data, sols)]

    def lift(self, Y: np.ndarray) -> np.ndarray:
        """Full-space vectors of reduced vectors ``Y`` (of this or an earlier, smaller basis)."""
        V = self.solver.V
        return V @ pad_to_basis(Y, V.shape[1])

    def pair(self, sols: list[Solution]) -> list[correlate.Pairing]:
        """Pair measured and model modes per state: by MAC where shapes are measured; frequency-only
        states with equal mode counts are paired jointly with one mode identity across states."""
        freq_only = [k for k, d in enumerate(self.data) if d.pairing_shapes is None]
        out: list = [None] * len(self.data)
        if len(freq_only) >= 2 and len({len(self.data[k].f_meas) for k in freq_only}) == 1:
            ref = sols[freq_only[0]]
            tracks = [self._track_model(ref, sols[k]) for k in freq_only]
            args = ([self.data[k].f_meas for k in freq_only], [sols[k].freqs_Hz for k in freq_only], tracks)
            pairs = correlate.pair_states_by_frequency(*args, min_freq_Hz=self.min_freq)
            if any(self.data[k].rule is not None for k in freq_only):
                # leaving a clearly visible mode unpaired costs its misfit: pairing and costs in turn
                seen = set()
                for _ in range(6):
                    key = tuple(tuple(p.model_index) for p in pairs)
                    skip = [self._skip_cost(self.data[k], sols[k], p.model_index) for k, p in zip(freq_only, pairs)]
                    new = correlate.pair_states_by_frequency(*args, min_freq_Hz=self.min_freq, skip_cost=skip)
                    if tuple(tuple(p.model_index) for p in new) == key or key in seen:
                        break
                    seen.add(key)
                    pairs = new
            for k, p in zip(freq_only, pairs):
                out[k] = p
        for k, (d, s) in enumerate(zip(self.data, sols)):
            if out[k] is None and d.pairing_shapes is None and d.rule is not None:
                cand = np.flatnonzero(s.freqs_Hz >= self.min_freq)
                if len(cand) >= len(d.f_meas):
                    index = d.rule.pair_by_frequency(d.f_meas, s.freqs_Hz, self._vis(d, s), cand)
                    out[k] = correlate.Pairing(model_index=np.asarray(index, int), mac=np.full(len(index), np.nan),
                                               method="frequency", unpaired_measured=[], unpaired_model=[])
            if out[k] is None:
                out[k] = correlate.pair_modes(d.f_meas, s.freqs_Hz, d.pairing_shapes,
                                              s.shapes if d.pairing_shapes is not None else None,
                                              threshold=self.mac_threshold, min_freq_Hz=self.min_freq)
        return out

    @staticmethod
    def _vis(d: StateData, s: Solution) -> np.ndarray:
        return d.rule.visibility(s.shapes, s.freqs_Hz)

    def _skip_cost(self, d: StateData, s: Solution, index) -> np.ndarray:
        if d.rule is None:
            return np.zeros(len(s.freqs_Hz))
        cost = d.rule.skip_costs(index, s.freqs_Hz, self._vis(d, s), d.f_meas)
        return np.where(s.freqs_Hz >= self.min_freq, cost, 0.0)

    def misfit_sets(self, sols: list[Solution], index: list) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per state, the clearly visible model modes in the band that ``index`` leaves unpaired and
        the nearest measured frequency of each (Hz): ``(modes, targets)`` (empty without a rule)."""
        out = []
        for d, s, ix in zip(self.data, sols, index):
            out.append(self._misfits(d, s, ix))
        return out

    def _misfits(self, d: StateData, s: Solution, index) -> tuple[np.ndarray, np.ndarray]:
        if d.rule is None:
            return np.zeros(0, int), np.zeros(0)
        cols, tgt = d.rule.misfits(index, s.freqs_Hz, self._vis(d, s), d.f_meas)
        keep = s.freqs_Hz[cols] >= self.min_freq
        return np.asarray(cols, int)[keep], np.asarray(tgt, float)[keep]

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
                 refine: bool = True, misfits: list | None = None, jacobian: bool = True) -> Evaluation:
        """Residuals ``ln(f_model / f_meas) / sigma`` and Jacobian at ``x``.

        ``index`` gives the model mode of each measured mode; with ``track`` (reference reduced
        vectors per state, columns = measured modes) each measured mode follows the model mode of
        largest mass-weighted MAC instead (mode crossings during a fit).  The unpaired, clearly
        visible model modes (misfits, :meth:`misfit_sets`) add residuals ``ln(f_u / f_near) / sigma``
        after each state's measured modes, rows ``(state, 0)``; ``misfits`` (per state ``(modes,
        targets, reference reduced vectors or None)``) holds that set fixed and follows its modes,
        else it is found at ``x``.  ``jacobian=False``: the residuals only (``J`` has no columns; the
        residuals are the same bits), for a caller that needs the misfit alone (the beta-P curve).
        """
        x = np.asarray(x, float)
        sols = self.solve_states(variant, x, refine=refine)
        r, J, rows, new_index, fmod, mis, sig, kn, modes, own = [], [], [], [], [], [], [], [], [], []
        for si, (d, sol) in enumerate(zip(self.data, sols)):
            idx = np.array(index[si])
            if track is not None and track[si] is not None:
                idx = self._follow(sol, track[si], idx)
            new_index.append(idx)
            if misfits is None:
                cols, tgt = self._misfits(d, sol, idx)
            else:
                cols, tgt, ref = misfits[si]
                cols = np.asarray(cols, int)
                if ref is not None and len(cols):
                    cols = self._follow(sol, ref, np.arange(len(cols)))
            ok = np.flatnonzero(idx >= 0)
            bad = np.flatnonzero(idx < 0)
            f = sol.freqs_Hz[idx[ok]]
            fm = d.f_meas[ok]
            near = d.nearest_mode(tgt)  # a misfit row takes the uncertainty of the measured mode it is held to
            s_row = np.concatenate([d.mode_sigma()[ok], d.mode_sigma()[bad], d.mode_sigma()[near]])
            sig.append(s_row)
            kn.append(np.concatenate([d.mode_known()[ok], d.mode_known()[bad], d.mode_known()[near]]))
            # the model mode of each row at the probe (an unpaired measured mode has none): whose mesh error it is
            modes.append(np.hstack([sol.shapes[:, idx[ok]], np.zeros((sol.shapes.shape[0], len(bad))),
                                    sol.shapes[:, cols]]))
            # half the mesh correction's first-order change since its reference (applied in solve_states): this
            # state's own uncertainty (jointid.diagnosis.mesh_error)
            u = 0.5 * np.abs(mesh_error.drift(d, sol))
            own.append(np.concatenate([u[idx[ok]], np.zeros(len(bad)), u[cols]]))
            e_row = np.concatenate([np.log(f / fm), np.full(len(bad), np.log1p(UNPAIRED_ERROR)),
                                    np.log(sol.freqs_Hz[cols] / tgt)])
            r.append(e_row / s_row)
            fm_all = np.full(len(d.f_meas), np.nan)
            fm_all[ok] = f
            fmod.append(fm_all)
            mis.append((np.asarray(cols, int), np.asarray(tgt, float), sol.freqs_Hz[cols]))
            dc = variant.dcoefficients(x, d.info) if jacobian else []
            Jb = np.zeros((len(ok) + len(bad) + len(cols), variant.n_params if jacobian else 0))
            use = np.concatenate([idx[ok], cols]).astype(int)
            sub = Solution(sol.freqs_Hz[use], sol.lam[use], sol.Y[:, use], sol.lam_all, sol.Y_all,
                           sol.kc, sol.mc, sol.shapes[:, use], sol.generation)
            at = np.concatenate([np.arange(len(ok)), len(ok) + len(bad) + np.arange(len(cols))]).astype(int)
            for j, dlam in enumerate(self.solver.sensitivities(sub, dc)):
                Jb[at, j] = dlam / (2 * np.maximum(sub.lam, 1e-9))
            J.append(Jb / s_row[:, None])
            rows += [(si, int(i) + 1) for i in ok] + [(si, int(i) + 1) for i in bad] + [(si, 0)] * len(cols)
        known, corr = known_budget(np.concatenate(kn), mode_correlation(np.hstack(modes)), np.concatenate(own))
        ev = Evaluation(x, np.concatenate(r), np.vstack(J), sols, new_index, rows, fmod, mis,
                        sigma=np.concatenate(sig), known=known if known.any() else None, known_corr=corr)
        return self.shapes.extend(ev, self.solver, [variant.dcoefficients(x, d.info) if jacobian else []
                                                    for d in self.data])

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

    def fit_starts(self, variant: Variant, starts, *, index=None) -> list["Fit"]:
        """:meth:`fit` of ``variant`` from each of ``starts`` in turn.  A start whose search on the subspace
        ends at the optimum an earlier start reached (:func:`same_optimum`) is not refined and checked
        again: it takes that fit (on the paper's diagnosis most starts end at one optimum)."""
        fits: list[Fit] = []
        for x0 in starts:
            fits.append(self.fit(variant, x0, index=index, known=fits))
        return fits

    def fit(self, variant: Variant, x0, *, index=None, max_loops: int = 4, verify: bool = False,
            known=()) -> "Fit":
        """Bounded least squares of ``variant`` from ``x0``; pairing re-done until stable.

        With a :class:`jointid.diagnosis.memo.FitMemo` (``memo``), a fit asked with exactly the inputs
        of a recorded one is evaluated at the recorded optimum, pairing and misfit set (checked in
        the full space, or certified by a check kept with the subspace) instead of being searched
        again; every fit searched is recorded.
        ``verify``: the optimum is certified (:meth:`ReducedSolver.verify`) and refitted if it fails.
        ``known``: fits of ``variant`` from other starts (:meth:`fit_starts`).
        """
        x0 = np.clip(np.asarray(x0, float), variant.lower, variant.upper)
        key = rec = None
        if self.memo is not None:
            if self._context is None:
                self._context = self.context_digest()
            key = self.memo.key(self._context, variant, x0, index, max_loops)
            rec = self.memo.get(key)
        if rec is not None:
            ev = self.evaluate(variant, rec["x"], rec["index"], refine=True,
                               misfits=[(c, t, None) for c, t in rec["misfits"]])
        else:
            ev = self._search(variant, x0, index, max_loops, known)
            if key is not None:
                self.memo.put(key, ev)
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

    def certify(self, fit: "Fit") -> "Fit":
        """``fit`` asked again from its optimum with the certificate (:meth:`fit` with ``verify``)."""
        return self.fit(fit.variant, fit.x, index=fit.ev.index, verify=True)

    def _search(self, variant: Variant, x0: np.ndarray, index, max_loops: int, known=()) -> Evaluation:
        """The search of :meth:`fit`: least squares on the subspace, refinement at the optimum, pairing
        re-done, until the pairing and the subspace are stable; returns the final evaluation.  When a
        least squares ends at the optimum of one of ``known`` with its pairing (:func:`same_optimum`), that
        fit's: the refinement and checks from there would find it again."""
        if index is None:
            index = [p.model_index for p in self.pair(self.solve_states(variant, x0))]
        ev = None
        for loop in range(max_loops + 3):
            sols = self.solve_states(variant, x0)
            track = [s.Y[:, np.clip(ix, 0, None)] for s, ix in zip(sols, index)]
            held = [(c, t, s.Y[:, c]) for (c, t), s in zip(self.misfit_sets(sols, index), sols)]
            cache = {}

            def ev_at(x):
                key = np.asarray(x, float).tobytes()
                if key not in cache:
                    cache.clear()
                    cache[key] = self.evaluate(variant, x, index, track, refine=False, misfits=held)
                return cache[key]

            if variant.n_params:
                # least squares on the current subspace, then refinement at the optimum; repeated
                # while the refinement changes the subspace (the optimum was not yet exact)
                res = least_squares(lambda x: ev_at(x).r, x0, jac=lambda x: ev_at(x).J,
                                    bounds=(variant.lower, variant.upper), method="trf", x_scale=1.0,
                                    xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=40)
                x_opt = res.x
                same = next((f for f in known if same_optimum(f, x_opt, index)), None)
                if same is not None:
                    return same.ev
            else:
                x_opt = x0
            size = (self.solver.generation, self.solver.V.shape[1])
            ev = self.evaluate(variant, x_opt, index, track, refine=True, misfits=held)
            changed_space = (self.solver.generation, self.solver.V.shape[1]) != size
            new = [p.model_index for p in self.pair(ev.solutions)]
            same_pairs = all(np.array_equal(a, b) for a, b in zip(new, ev.index))
            now = self.misfit_sets(ev.solutions, ev.index)
            same_pairs = same_pairs and all(np.array_equal(a[0], m[0]) and np.allclose(a[1], m[1])
                                            for a, m in zip(now, ev.misfits))
            if not same_pairs:
                index = new
            x0 = x_opt
            if same_pairs and (not changed_space or not variant.n_params):
                break
        return ev


SAME_OPTIMUM = 0.05
"""A start's optimum is an earlier start's when every parameter lies within this fraction of that fit's
standard error (its scaled covariance) of it, with the same pairing: a difference no interval can show."""


def same_optimum(fit: "Fit", x, index) -> bool:
    """Whether ``x`` with pairing ``index`` is the optimum of ``fit`` (:data:`SAME_OPTIMUM`)."""
    if index is None or not all(np.array_equal(a, b) for a, b in zip(fit.ev.index, index)):
        return False
    return standard_distance(fit, x) <= SAME_OPTIMUM


def shares_terms(a: System, b: System) -> bool:
    """Whether a reduced solver of system ``a`` serves ``b``: the same system, or one of the same terms
    (:func:`jointid.diagnosis.terms.build_systems`: configurations that differ only in coefficients)."""
    return a is b or (a.stiffness is b.stiffness and a.mass is b.mass and a.probe is b.probe
                      and np.array_equal(a.fixed, b.fixed))


def term_directions(system: System) -> list[tuple[dict, dict]]:
    """Seed directions of the reduced solver: the joint layers of all carriages per direction, the rail fixing,
    the foundation, the mounts and each added-mass layer, not the parts' solids (:func:`is_solid_term`)."""
    groups = {}
    for name in system.stiffness:
        if "@" in name:
            d = term_component(name)
            groups.setdefault(d, {})[name] = 1.0
    out = [(g, {}) for g in groups.values()]
    for name in ("K_railfix", "K_foundation", "K_mount"):
        if name in system.stiffness:
            out.append(({name: 1.0}, {}))
    for name in system.mass:
        if not is_solid_term(name):
            out.append(({}, {name: 1.0}))
    return out


def refit(diag: Diagnoser, fit: Fit, spec: EffectSpec, t_hat: np.ndarray, *, verify: bool = True) -> Fit:
    """Fit ``fit.variant + spec`` from several starts of the new parameters; best by chi-square."""
    var = fit.variant.extended(spec)
    q = var.n_params - fit.variant.n_params
    starts = refit_starts(spec, float(t_hat[0])) if q == 1 else [[rounded_start(t) for t in np.clip(t_hat, 0, None)]]
    best = best_fit(diag.fit_starts(var, [np.concatenate([fit.x, np.atleast_1d(s)]) for s in starts],
                                    index=fit.ev.index))
    if q == 1 and at_its_null(spec, best.x[-1]):  # every start ended at the null: try the effect at typical sizes
        more = sized_starts(spec, starts)
        best = best_fit([best] + diag.fit_starts(var, [np.concatenate([fit.x, [s]]) for s in more], index=fit.ev.index))
    if verify:
        best = diag.certify(best)
    return best
