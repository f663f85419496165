"""The diagnosis loop: compare, calibrate, score, refit, rank, verdict, drift (docs/effects.md).

:func:`diagnose` is the driver; each step is a function of its own, called in this order (the
reduced solver's subspace grows with every solve, so the order is part of the result):

1. :func:`compare_reference` — the baseline calibrated on the reference state;
2. the baseline on all states, then :func:`calibrate_ladder` — the configured effects one by one;
3. :func:`score_candidates` — a score test of every library effect not in the model;
4. :func:`refit_candidates` — the leading candidates refitted, AICc and noise-level check;
5. :func:`combinations` — pairs of the leading candidates, when no single one explains; then every
   fit judged with the model error (:mod:`jointid.diagnosis.judging`: QAICc, weights, support);
6. :func:`jointid.diagnosis.ambiguity.absorption_notes` — candidates the fitted joints could imitate;
7. :func:`jointid.diagnosis.ambiguity.explain_tie` — how tied candidates differ, the measurement that
   would decide;
8. :func:`jointid.diagnosis.preload.identifiable_fits` — what the force levels identify of the contact law;
9. :func:`jointid.diagnosis.verdict.verdict_text` — the verdict in words;
10. :func:`drift_table` and :func:`model_notes` — per-state drift, identifiability, unpaired modes.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from jointid.config.typed_diagnosis import DiagnosisSettings
from jointid.correlate import pairing as correlate
from jointid.diagnosis.ambiguity import absorption_notes, explain_tie, tie_groups
from jointid.diagnosis.combine import combine_candidates, refit_at, refit_on_ladder
from jointid.diagnosis.effects import EFFECTS, Enabled, enabled_effects
from jointid.diagnosis.fitting import Diagnoser, Fit, best_fit, print_log, refit
from jointid.diagnosis.judging import judge_fits, model_error_of
from jointid.diagnosis.mesh_budget import mesh_budget, refit_answer
from jointid.diagnosis.predictive import check_pairs
from jointid.diagnosis.preload import identifiable_fits, profile_candidate
from jointid.diagnosis.results import refit_row, standard_distance
from jointid.diagnosis.starts import chi2_tie
from jointid.diagnosis.statistics import identifiability, score_candidate, state_contrasts
from jointid.diagnosis.tables import (compare_tables, drift_table, parameter_table, ranking_frame,
                                      state_errors_table)
from jointid.diagnosis.terms import System
from jointid.diagnosis.variants import EffectSpec, StateData, Variant
from jointid.diagnosis.verdict import Findings, verdict_text
from jointid.errors import DataError
from jointid.fe.reduced import ReducedSolver
from jointid.identification.model_error import NO_MODEL_ERROR, ModelError
from jointid.progress import Steps


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
    combinations: pd.DataFrame = field(default_factory=pd.DataFrame)
    next_measurements: pd.DataFrame = field(default_factory=pd.DataFrame)
    preload_curve: pd.DataFrame = field(default_factory=pd.DataFrame)
    identifiable: dict = field(default_factory=dict)
    absorbed: list = field(default_factory=list)
    model_error: ModelError = NO_MODEL_ERROR


def default_options() -> dict:
    """The defaults of the ``diagnosis`` config section, from the schema (for a config not validated)."""
    from jointid.config.schema import load_schema, subschema  # noqa: PLC0415

    props = subschema(load_schema(), "diagnosis")["properties"]
    return {k: v["default"] for k, v in props.items()}


def diagnose(system: System, settings: DiagnosisSettings, data: list[StateData], *, effects: dict | None = None,
             candidates: list[str] | None = None, n_refit: int | None = None, alpha: float | None = None,
             reference_state: str | None = None, solver: ReducedSolver | None = None,
             start_basis=None, memo=None, compare: bool = True, drift: bool = True, tables_ready=None,
             log=print_log) -> Diagnosis:
    # many parameters: the loop's options (effects, candidates, refits, solver reuse, ...), keyword with defaults
    """Run the whole loop on measured states: compare, calibrate, score, refit, combine, rank, ladder, drift.

    Parameters
    ----------
    system : System
    settings : DiagnosisSettings
        Of the validated configuration (joints, solver, identify, diagnosis ...).
    data : list of StateData
    effects : dict, optional
        Effects enabled in the model (an ``effects`` config section); default ``settings.effects``.
    candidates : list of str, optional
        Library effects to test (default: all not enabled).
    n_refit, alpha : optional
        Override ``diagnosis.n_refit`` (candidates refitted) and ``diagnosis.alpha`` (p-value to explain).
    reference_state : str, optional
        State the baseline is calibrated on for the comparison step (default: the state with the
        smallest motor force, first in order).
    solver : ReducedSolver, optional
        A reduced solver of the same system to reuse (its subspace only grows; several datasets of one rig).
    start_basis : jointid.fe.warmstart.Kept, optional
        A basis the solver starts from (kept from an earlier run, :mod:`jointid.fe.warmstart`).
    memo : jointid.diagnosis.memo.FitMemo, optional
        Fits recorded on the same model (:meth:`Diagnoser.fit`); every fit is recorded in it.
    compare, drift : bool
        Run the comparison step (baseline calibrated on the reference state) and the per-state drift
        fits (both on by default).
    tables_ready : callable, optional
        Given the page figures' :class:`Diagnosis` fields (``ladder, compare, current, ranking, point_residuals,
        mac``) as keywords once final, before the drift fits (the stage draws the figures beside those).

    Returns
    -------
    Diagnosis
    """
    t_start = time.time()
    opt = {**default_options(), **settings.diagnosis}
    opt.update({k: v for k, v in (("n_refit", n_refit), ("alpha", alpha)) if v is not None})
    alpha = float(opt["alpha"])
    enabled = enabled_effects(settings.effects if effects is None else effects)
    data = list(data)  # the mesh's errors replace its states by copies (step 1b); the caller's list stays
    diag = Diagnoser(system, settings, data, solver=solver, start_basis=start_basis, memo=memo, log=log)
    notes = []
    base = Variant(system, settings, [])
    check_enough_data(data, base)
    x0, tables = compare_reference(diag, base, reference_state, compare, notes, log)
    if opt.get("mesh_error", True):
        mesh_budget(diag, base, x0, notes, log)
    log("diagnosis: calibrating the baseline on all states")
    fit_base = diag.fit(base, x0, verify=not enabled)
    compare_tab, mac_mats, shape_res = tables or compare_tables(diag, base, fit_base.x)
    fits, current, ladder_rows, rows, between_share = search_best_basin(diag, fit_base, enabled, candidates,
                                                                        effects, opt, notes, log)
    current_table = compare_tables(diag, current.variant, current.x)[0]
    combos, ranking, me, current_weight = combine_and_judge(diag, current, rows, fits, opt, log)
    absorbed = absorption_notes(diag, current, rows, ranking, float(opt["absorption_shift_pct"]), me)
    tie_detail, nxt = explain_tie(diag, ranking, fits, me)
    ident, curve = identifiable_fits(diag, current, fits, ranking, combos, log)
    if opt.get("mesh_error", True):  # step 8b: the answer's value at its own mesh error, where it changed the structure
        refit_answer(diag, current, fits, ranking, combos, notes, log)
    findings = Findings(current, ranking, alpha, between_share, combos, absorbed, tie_detail, nxt, ident,
                        int(opt["max_effects"]), me, current_weight)
    verdict, explained_by = verdict_text(findings, diag.data)
    ladder_rows += suggested_ladder(diag, fits, explained_by, ranking)
    shown = {"ladder": pd.DataFrame(ladder_rows), "compare": compare_tab, "current": current_table, "ranking": ranking,
             "point_residuals": correlate.point_residuals(shape_res), "mac": mac_mats}  # final: nothing below changes them
    if tables_ready is not None:
        tables_ready(**shown)
    drift_tab = drift_table(diag, current, log, skip=not drift)
    notes += model_notes(current, data) + diag.shapes.note() + absorbed
    return Diagnosis(**shown, compare_summary=correlate.error_summary(compare_tab), drift=drift_tab,
                     shape_residuals=shape_res, verdict=verdict, explained_by=explained_by, fits=fits, notes=notes,
                     parameters=parameter_table(fits), timing_s=time.time() - t_start, solver=diag.solver,
                     combinations=combos, next_measurements=nxt, preload_curve=curve, identifiable=ident,
                     absorbed=absorbed, model_error=me)


def search(diag: Diagnoser, fit_base: Fit, enabled: list[Enabled], candidates, effects, opt: dict, log):
    """Steps 2-4: the ladder on the calibrated baseline, the candidates scored and the leading ones refitted.
    Returns ``(fits, current model, ladder rows, candidate rows, between-state share)``."""
    fits, current, ladder_rows = calibrate_ladder(diag, fit_base, enabled, log)
    current, rows, between_share = score_candidates(diag, current, enabled, candidates, effects)
    alpha = float(opt["alpha"])
    refit_candidates(diag, current, rows, fits, int(opt["n_refit"]), alpha, log, list(fits.values())[:-1])
    profile_candidate(diag, current, rows, fits, alpha, log)
    return fits, current, ladder_rows, rows, between_share


def search_best_basin(diag: Diagnoser, fit_base: Fit, enabled: list[Enabled], candidates, effects, opt: dict,
                      notes: list, log):
    # many parameters: those of search, and the notes the better basin adds to
    """Steps 2-4c: :func:`search`, and once more from the better basin when the baseline's calibration was in
    a worse one (:func:`better_basin`; a note says so).  Returns what :func:`search` returns."""
    out = search(diag, fit_base, enabled, candidates, effects, opt, log)
    better = None if enabled else better_basin(diag, out[1], out[0], log)
    if better is None:
        return out
    notes.append(better[1])
    return search(diag, better[0], enabled, candidates, effects, opt, log)


def better_basin(diag: Diagnoser, current: Fit, fits: dict, log) -> tuple[Fit, str] | None:
    """Step 4c: a candidate's refit that fits better than the current model while its effect's 95 % interval
    holds the effect's null (:func:`at_null`) has found better joint parameters, not the effect: the current
    model's calibration sat in a worse basin (e.g. frequencies only and few modes, where the pairing has more
    than one fit).  The current model is refitted from each such refit's joints; the best of those that fit
    better than the current model is returned, with a note, for the search to start again from it (once).
    None when no refit qualifies or none of those fits better.  Only another basin counts: joints outside the
    current model's 95 % intervals (:func:`outside_interval`) at a chi-square lower by more than the solver's
    accuracy can move it (:func:`jointid.diagnosis.starts.chi2_tie`).  A refit that found the current optimum
    again to the search's tolerance (the coarse rig: 541.70 against 541.71, the joints 0.002 apart in log
    against intervals of ±0.18 to ±0.47) starts no second search."""
    p, q = current.variant.n_params, len(current.variant.slots)
    tol = chi2_tie(current)
    best, via = None, None
    for name, f in sorted(fits.items(), key=lambda kv: kv[1].chi2):
        if (not name.startswith("+") or f.chi2 >= current.chi2 - tol or not at_null(f, q)
                or not outside_interval(current, f.x[:p])):
            continue
        log(f"diagnosis: {name[1:]} fits better at its null, with joints outside the current model's 95 % "
            "intervals: the current model refitted from them")
        g = diag.fit(current.variant, f.x[:p], index=f.ev.index)
        if g.chi2 < (best or current).chi2 - tol and outside_interval(current, g.x[:p]):
            best, via = g, name[1:]
    if best is None:
        return None
    return best, (f"the current model's first calibration was not its best fit: refitted from the joints of the "
                  f"{via} refit (which fitted better with {via} at its null), its chi-square fell from "
                  f"{current.chi2:.1f} to {best.chi2:.1f}; the candidates were scored and refitted again from it")


def outside_interval(f: Fit, x) -> bool:
    """Whether any parameter of ``x`` (the first ``len(x)`` of ``f``'s) lies outside ``f``'s 95 % interval
    (its scaled covariance): another basin, not ``f``'s own optimum found again to the search's tolerance."""
    return standard_distance(f, x) > 1.96


def at_null(f: Fit, n_slots: int) -> bool:
    """Whether every effect parameter ``f`` adds beyond the first ``n_slots`` has the effect's null (test
    variable 0) inside its 95 % interval (the fit's scaled covariance)."""
    cov = f.scaled_covariance()
    p = f.variant.n_params - (len(f.variant.slots) - n_slots)
    return all(float(f.x[j]) - 1.96 * np.sqrt(max(cov[j, j], 0.0)) <= 0.0 for j in range(p, f.variant.n_params))


def check_enough_data(data: list[StateData], base: Variant) -> None:
    """Raise :class:`DataError` unless the measured frequencies outnumber the fitted parameters."""
    n_obs = sum(len(d.f_meas) for d in data)
    if n_obs <= base.n_params:
        raise DataError(f"diagnosis: {n_obs} measured frequencies for {base.n_params} fitted parameters "
                        f"({', '.join(base.labels)}): a fit leaves no residual to test an effect with — "
                        "measure more modes or states, or fix parameters (joints.fixed)")


def compare_reference(diag: Diagnoser, base: Variant, reference_state: str | None, compare: bool,
                      notes: list, log) -> tuple[np.ndarray, tuple | None]:
    """Step 1: the baseline calibrated on the reference state alone, and its comparison tables.

    Returns the start vector of the all-states calibration and ``(compare table, MAC matrices,
    shape residuals)``, or None when the comparison is off or the reference state alone cannot
    determine the parameters (then a note says so and the caller compares the all-states baseline).
    """
    data = diag.data
    ref = reference_state or min(data, key=lambda d: d.info.em_force_N).name
    if compare and sum(len(d.f_meas) for d in data if d.name == ref) <= base.n_params:
        compare = False  # the reference state alone cannot determine the parameters
        notes.append(f"the comparison uses the baseline calibrated on all states: {ref} alone has no more "
                     f"measured modes than the {base.n_params} fitted parameters")
    x0 = base.x_start()
    diag.ensure_solver(base, x0)
    if not compare:
        return x0, None
    sub = Diagnoser(diag.system, diag.settings, [d for d in data if d.name == ref], n_modes=diag.n_modes,
                    solver=diag.solver, memo=diag.memo, log=log)
    log(f"diagnosis: calibrating the baseline on {ref}")
    fit_ref = sub.fit(base, x0)
    return fit_ref.x, compare_tables(diag, base, fit_ref.x)


def calibrate_ladder(diag: Diagnoser, fit_base: Fit, enabled: list[Enabled], log) -> tuple[dict, Fit, list]:
    """Step 2: the configured effects added to the calibrated baseline one by one, each refitted.

    Returns the fits by ladder label (``baseline``, ``+<effect>`` ...), the last fit (the current
    model) and the ladder rows (:func:`state_errors_table`).
    """
    ladder_rows = state_errors_table(diag, fit_base, "baseline")
    fits = {"baseline": fit_base}
    current = fit_base
    for en in enabled:
        spec = EffectSpec(en.effect, dict(en.values), dict(en.options),
                          [p.name for p in en.effect.params] if en.fit else [])
        var = current.variant.extended(spec)
        log(f"diagnosis: calibrating {var.name}")
        if spec.free and not set(spec.free) & set(en.configured):
            # no value given: fitted exactly as the candidate search refits it (the same starts), so
            # the ladder's row is the refit the ranking reported for this effect
            best = refit_at(diag, current, spec)
        else:
            # from the configured values and from the effect at (almost) its null: a strong start can
            # lock onto a pairing of its own, with the new modes it brings into the band as misfits
            x0 = np.concatenate([current.x, [en.effect.param(n).to_t(en.values[n]) for n in spec.free]])
            near = np.concatenate([current.x, [en.effect.param(n).t_near_null() for n in spec.free]])
            starts = [x0] if np.allclose(near, x0) else [x0, near]
            best = best_fit(diag.fit_starts(var, starts, index=current.ev.index))
        current = diag.certify(best) if en is enabled[-1] else best
        label = "+" + en.effect.name
        fits[label] = current
        ladder_rows += state_errors_table(diag, current, label)
    return fits, current, ladder_rows


def score_candidates(diag: Diagnoser, current: Fit, enabled: list[Enabled], candidates: list[str] | None,
                     effects: dict | None) -> tuple[Fit, list, float]:
    """Step 3: score test of every candidate effect at the current model (all states and between states).

    Returns the current fit re-evaluated at its optimum, the rows ``(ranking row, EffectSpec or None,
    score-test dict or None)`` per candidate and the between-state share of ``r^T r``.
    """
    data = diag.data
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
        spec = EffectSpec.candidate(eff, (effects or diag.settings.effects or {}).get(name))
        why = eff.requires(diag.system, diag.settings, [d.info for d in data], spec.options) if eff.requires else None
        row = {"effect": name, "title": eff.title, "parameter": eff.params[0].name, "unit": eff.params[0].unit}
        if why:
            row.update({"explained_fraction": 0.0, "score": 0.0, "p_value": 1.0, "note": f"not applicable: {why}"})
            rows.append((row, None, None))
            continue
        st = score_candidate(diag, current, spec, C, row)
        rows.append((row, spec, st))
    return current, rows, between_share


def refit_candidates(diag: Diagnoser, current: Fit, rows: list, fits: dict, n_refit: int, alpha: float,
                     log, rungs: list[Fit] = ()) -> None:
    """Step 4: refit the ``n_refit`` leading candidates (by score); fills their ranking rows and ``fits``.

    A measured mode that no model mode pairs with is a residual without a sensitivity: the score test
    cannot see that a candidate would bring the missing mode.  With such modes every applicable
    candidate is refitted (the score-led ones first), its pairing re-done during the fit.  When none of
    the score-led refits explains the data, the other applicable candidates are refitted too: the
    first-order test is blind to an effect the joints have absorbed at the current optimum.
    With effects enabled (``rungs``: the ladder's fits below ``current``) a candidate is refitted as
    the pair of the last enabled effect and itself (:func:`refit_on_ladder`), from the starts the
    pair has in a run without that effect enabled.
    """
    order = sorted([r for r in rows if r[1] is not None and r[2]["sign_ok"] and r[0]["score"] > 0
                    and r[2]["collinearity"] >= 1e-3 and r[0]["explained_fraction"] >= 0.01],
                   key=lambda r: -r[0]["score"])
    rest = sorted([r for r in rows if r[1] is not None and r not in order[:n_refit]
                   and r[2]["collinearity"] >= 1e-3], key=lambda r: -r[0]["score"])
    if any(p.unpaired_measured for p in current.pairings):
        order, n_refit, rest = order[:n_refit] + rest, len(order[:n_refit]) + len(rest), []
    order = order[:n_refit]
    steps = Steps(len(order))
    for i, (row, spec, st) in enumerate(order):
        _refit_one(diag, current, rungs, row, spec, st, fits, alpha, log, steps, verify=i == 0)
    if rest and not any(bool(r[0].get("explains")) for r in order):
        # none explains: the first-order test may be blind where the joints have absorbed an effect
        # (its direction then looks like no improvement, or the wrong sign), so the rest are refitted too
        steps = Steps(len(rest))
        for row, spec, st in rest:
            _refit_one(diag, current, rungs, row, spec, st, fits, alpha, log, steps, verify=False)


def _refit_one(diag, current, rungs, row, spec, st, fits, alpha, log, steps, *, verify: bool) -> None:
    # many parameters: the diagnoser, the model and its ladder, the candidate's row, spec and test, the outputs
    """One candidate's refit (:func:`refit_candidates`): its ranking row filled, its fit kept in ``fits``."""
    log(f"diagnosis: refitting {current.variant.name} + {row['effect']} {steps.next()}")
    f = refit_on_ladder(diag, rungs, current, spec, verify=verify) if rungs else \
        refit(diag, current, spec, st["t_hat"], verify=verify)
    row.update(refit_row(f, current, diag.data, alpha))
    fits["+" + row["effect"]] = f


def combine_and_judge(diag: Diagnoser, current: Fit, rows: list, fits: dict, opt: dict, log):
    """Steps 4b-5: whether anything needs explaining (nothing explains when the current model fits within
    the noise), the pairs when no single refit explains (:func:`combinations`), every fit judged with
    the model error (:func:`jointid.diagnosis.judging.judge_fits`) and the ranking with its ties.

    Returns ``(combinations frame, ranking, model error, the current model's weight)``.
    """
    needed = current.p_value < float(opt["alpha"])
    for row, _, _ in rows:
        if "explains" in row:
            row["explains"] = bool(row["explains"] and needed)
    any_explains = any(bool(r[0].get("explains")) for r in rows)
    combos = combinations(diag, current, rows, fits, opt, log) if needed and not any_explains else []
    me = model_error_of({**fits, "current": current}, diag.data)
    current_weight = judge_fits(current, fits, [r[0] for r in rows], combos, diag.data, me)
    check_pairs(combos, fits, diag.data, me)
    ranking = ranking_frame([r[0] for r in rows])
    ranking.attrs["tie_delta_aicc"] = float(opt["tie_delta_aicc"])
    ranking.attrs["model_error"] = me
    # the error budget every row was judged at: stated noise, known (mesh) error and model error, per mode
    ranking["sigma_noise_pct"] = 100 * me.sigma_noise_rel
    ranking["sigma_known_pct"] = 100 * me.sigma_known_rel
    ranking["sigma_model_pct"] = 100 * me.sigma_model_rel
    ranking["indistinguishable_from"] = tie_groups(ranking, float(opt["tie_delta_aicc"]))
    return combination_frame(combos), ranking, me, current_weight


def combinations(diag: Diagnoser, current: Fit, rows: list, fits: dict, opt: dict, log) -> list[dict]:
    """Step 5: pairs of the leading single refits (:func:`combine_candidates`) when ``max_effects``
    allows: it counts the library effects of one model, the enabled ones included (a pair on top of
    one enabled effect is a model of three); their fits join ``fits`` under ``+a+b``."""
    singles = {r[0]["effect"]: fits["+" + r[0]["effect"]] for r in rows if "+" + r[0]["effect"] in fits}
    if int(opt["max_effects"]) < len(current.variant.effects) + 2 or len(singles) < 2:
        return []
    combo_rows, combo_fits = combine_candidates(diag, current, singles, int(opt["n_combine"]), float(opt["alpha"]), log)
    fits.update(combo_fits)
    return combo_rows


def combination_frame(rows: list[dict]) -> pd.DataFrame:
    """The judged pairs (:func:`jointid.diagnosis.judging.judge_fits`) as a table: those explaining the
    data at the noise first, then by delta QAICc."""
    if not rows:
        return pd.DataFrame()
    return pd.DataFrame(sorted(rows, key=lambda r: (not r["explains"], r["delta_qaicc"]))).reset_index(drop=True)


def suggested_ladder(diag: Diagnoser, fits: dict, explained_by: str, ranking: pd.DataFrame) -> list[dict]:
    """Ladder rows of the suggested model: ``+A (suggested)``, or ``+A`` then ``+A+B (suggested)``
    for a combination (forward selection); one row per tied candidate.  When nothing explains the
    data, the best single refit and the best pair, marked ``(best, above the noise)``: how far the
    library gets."""
    if explained_by == "none needed":
        return []
    rows = []
    if explained_by == "unexplained":
        refitted = ranking[ranking["delta_aicc"].notna()]
        if not len(refitted):
            return []
        best = min(refitted["effect"], key=lambda n: fits["+" + n].aicc)
        rows += state_errors_table(diag, fits["+" + best], f"+{best} (best, above the noise)")
        pairs = [k for k in fits if k.count("+") == 2]
        if pairs:
            p = min(pairs, key=lambda k: fits[k].aicc)
            if fits[p].aicc < fits["+" + best].aicc:
                rows += state_errors_table(diag, fits[p], f"{p} (best pair, above the noise)")
        return rows
    if "+" in explained_by:
        a, b = explained_by.split("+")
        rows += state_errors_table(diag, fits["+" + a], f"+{a}")
        return rows + state_errors_table(diag, fits[f"+{a}+{b}"], f"+{a}+{b} (suggested)")
    for name in explained_by.split(" or "):
        rows += state_errors_table(diag, fits["+" + name], f"+{name} (suggested)")
    return rows


def model_notes(current: Fit, data: list[StateData]) -> list[str]:
    """Step 10: notes on the current model: a weakly identifiable combination, unpaired measured modes."""
    notes = []
    ident = identifiability(current.ev.J, current.variant.labels)
    if ident["flag"]:
        notes.append(f"weakly identifiable combination of the fitted parameters (sigma_min/sigma_max = "
                     f"{ident['ratio']:.1e}): {ident['weak']}")
    for d, p in zip(data, current.pairings):
        if p.unpaired_measured:
            notes.append(f"{d.name}: measured mode(s) {', '.join(str(i + 1) for i in p.unpaired_measured)} "
                         "have no model partner (listed in compare.csv)")
    return notes
