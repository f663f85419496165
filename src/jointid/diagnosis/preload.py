"""What force levels identify of the contact law ``k = alpha (F_c + P)^beta`` (docs/effects.md).

The ``em_preload`` effect scales the joints of carriage c in state s by ``((F_c,s + P) / (F_c,0 +
P))^beta`` (F_c,s the carriage load under the motor attraction, F_c,0 under the weight alone, P the
block preload).  With **two** force levels the data fix one number per carriage and direction: the
stiffness ratio between the states.  Every pair (beta, P) on the curve ``beta(P) = ln R /
ln((F_c,1 + P) / (F_c,0 + P))`` gives that same ratio, so beta and P cannot be told apart;
:func:`preload_curve` tabulates the curve (with the chi-square each point gives, to show it is flat)
and :func:`stiffness_ratios` reports the ratio with its interval.  With **three or more** force
levels the curvature of the law in F separates them: :func:`profile_preload` profiles the
chi-square over P (beta and the joints refitted at each P) and gives P with its interval.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from jointid.diagnosis.ambiguity import CHI2_1_95
from jointid.diagnosis.effects import contact_directions, pressure_ratio
from jointid.diagnosis.fitting import Diagnoser, Fit
from jointid.diagnosis.memo import variant_signature
from jointid.diagnosis.variants import EffectSpec, Variant

__all__ = ["PRELOAD_GRID_N", "force_levels", "profile_preload", "profile_candidate", "preload_curve",
           "stiffness_ratios", "identifiable_text", "identify_preload", "identifiable_fits"]

PRELOAD_GRID_N = (0.0, 25.0, 50.0, 100.0, 200.0, 400.0, 800.0, 1600.0, 3200.0, 6400.0)
"""Block preloads tried (N): from none to several times a catalogue block's medium preload."""


def force_levels(data) -> list[float]:
    """The distinct motor forces of the measured states (N), ascending."""
    return sorted({round(float(d.info.em_force_N), 6) for d in data})


def _with_preload(variant: Variant, k: int, P: float) -> Variant:
    """``variant`` with effect ``k``'s option ``preload_N`` set to ``P``."""
    effects = list(variant.effects)
    s = effects[k]
    effects[k] = EffectSpec(s.effect, dict(s.values), {**s.options, "preload_N": float(P)}, list(s.free))
    return Variant(variant.system, variant.settings, effects, theta_fixed=variant.theta_fixed)


def _slot(variant: Variant) -> tuple[int, int] | None:
    """(effect number, position in x) of em_preload's beta in ``variant``, None without it."""
    for k, (i, p) in enumerate(variant.slots):
        if variant.effects[i].effect.name == "em_preload" and p.name == "beta":
            return i, variant.p + k
    return None


def profile_preload(diag: Diagnoser, fit: Fit, log) -> tuple[Fit, pd.DataFrame, dict]:
    """Profile the chi-square of ``fit`` (a variant with em_preload) over the block preload P.

    At every P beta and the joints are refitted (continued from the nearest P done).  The grid
    :data:`PRELOAD_GRID_N` brackets the minimum, a bounded scalar search in ``ln(P + 25 N)`` refines
    it, and root finding gives the ends of the 95 % profile interval (chi-square within 3.84 of its
    minimum).  Returns the best fit (em_preload option ``preload_N`` at the best P, the profile
    attached as ``preload_profile``), the table of every P refitted (``preload_N, beta, chi2``) and
    ``{"preload_N", "low", "high", "beta_low", "beta_high"}``: P with its interval, and the range of
    beta over that interval (each end widened by its conditional 95 % interval).
    """
    from scipy.optimize import brentq, minimize_scalar

    k, j = _slot(fit.variant)
    done: dict[float, Fit] = {}

    def at(P: float) -> Fit:
        P = float(max(P, 0.0))
        if P not in done:
            near = min(done, key=lambda q: abs(math.log(q + 25) - math.log(P + 25))) if done else None
            x0 = done[near].x if near is not None else fit.x
            done[P] = diag.fit(_with_preload(fit.variant, k, P), x0, index=fit.ev.index)
        return done[P]

    grid = [at(P).chi2 for P in PRELOAD_GRID_N]
    i = int(np.argmin(grid))
    lo_P, hi_P = PRELOAD_GRID_N[max(i - 1, 0)], PRELOAD_GRID_N[min(i + 1, len(PRELOAD_GRID_N) - 1)]
    u = lambda P: math.log(P + 25.0)  # noqa: E731 - the search variable
    minimize_scalar(lambda v: at(math.exp(v) - 25.0).chi2, bounds=(u(lo_P), u(hi_P)), method="bounded",
                          options={"xatol": 0.02})
    P_best = min(done, key=lambda q: done[q].chi2)
    # the profile's 95 % level, widened as the intervals are when the fit is worse than the noise
    level = done[P_best].chi2 + CHI2_1_95 * done[P_best].interval_scale(1) ** 2
    g = lambda v: at(math.exp(v) - 25.0).chi2 - level  # noqa: E731
    ends = []
    for side in (-1, 1):
        pts = sorted(P for P in PRELOAD_GRID_N if (P - P_best) * side > 0)
        pts = pts if side > 0 else pts[::-1]
        end = math.inf if side > 0 else 0.0
        prev = P_best
        for P in pts:
            if at(P).chi2 > level:
                end = math.exp(brentq(g, *sorted((u(prev), u(P))), xtol=0.01)) - 25.0
                break
            prev = P
        else:
            end = math.inf if side > 0 else 0.0
        ends.append(end)
    b_lo = at(ends[0])
    b_hi = at(ends[1]) if math.isfinite(ends[1]) else at(PRELOAD_GRID_N[-1])
    betas = [_beta_ci(b_lo, j)[0], _beta_ci(b_hi, j)[1], *_beta_ci(done[P_best], j)]
    est = {"preload_N": float(P_best), "low": float(max(ends[0], 0.0)), "high": float(ends[1]),
           "beta_low": float(min(betas)), "beta_high": float(max(betas))}
    prof = pd.DataFrame([{"preload_N": P, "beta": float(f.x[j]), "chi2": f.chi2} for P, f in sorted(done.items())])
    log(f"diagnosis: em_preload profiled over the block preload ({len(done)} refits): P = {P_best:.0f} N "
        f"[{est['low']:.0f}, {est['high']:.0f}], beta {est['beta_low']:.3f} .. {est['beta_high']:.3f}")
    best = done[P_best]
    best.preload_profile = est
    return best, prof, est


def stiffness_ratios(fit: Fit, data, beta_ci: tuple[float, float]) -> pd.DataFrame:
    """Joint stiffness of each loaded state over the weight-only state, per carriage, in the law's
    directions, with the interval that ``beta_ci`` maps to (the ratio is monotone in beta)."""
    k, j = _slot(fit.variant)
    spec = fit.variant.effects[k]
    beta = float(fit.x[j])
    rows = []
    ref = min(data, key=lambda d: d.info.em_force_N)
    for d in data:
        if d.info.em_force_N == ref.info.em_force_N:
            continue
        rho = pressure_ratio(fit.variant.system, d.info, spec.options)
        for c, r in enumerate(rho):
            rows.append({"state": d.name, "reference_state": ref.name, "carriage": c,
                         "directions": ",".join(sorted(contact_directions(fit.variant.system, spec.options))),
                         "stiffness_ratio": float(r ** beta), "ci95_low": float(r ** beta_ci[0]),
                         "ci95_high": float(r ** beta_ci[1])})
    return pd.DataFrame(rows)


def preload_curve(diag: Diagnoser, fit: Fit) -> pd.DataFrame:
    """The (beta, P) pairs that give the fitted stiffness ratio (geometric mean over the carriages)
    of the most loaded state, with the chi-square each gives at the fitted joints (no refit).  With a
    memo (``diagnosis.reuse_subspace``) a curve asked again at the same fit is read from it, exactly."""
    parts = (variant_signature(fit.variant), np.asarray(fit.x, float), [np.asarray(i, np.int64) for i in fit.ev.index])
    return diag.remembered("preload_curve", parts, lambda: _preload_curve(diag, fit), _curve_record, _curve_from_record)


def _curve_record(curve: pd.DataFrame) -> list:
    return [[float(r.preload_N).hex(), float(r.beta).hex(), float(r.chi2).hex(), bool(r.fitted)] for r in curve.itertuples()]


def _curve_from_record(rec: list) -> pd.DataFrame:
    return pd.DataFrame([{"preload_N": float.fromhex(P), "beta": float.fromhex(b), "chi2": float.fromhex(c),
                          "fitted": bool(f)} for P, b, c, f in rec])


def _preload_curve(diag: Diagnoser, fit: Fit) -> pd.DataFrame:
    k, j = _slot(fit.variant)
    spec = fit.variant.effects[k]
    beta = float(fit.x[j])
    loaded = max(diag.data, key=lambda d: d.info.em_force_N)
    P0 = float(spec.options.get("preload_N", 0.0))
    log_ratio = beta * float(np.mean(np.log(pressure_ratio(fit.variant.system, loaded.info, spec.options))))
    rows = []
    for P in PRELOAD_GRID_N:
        opts = {**spec.options, "preload_N": P}
        lr = float(np.mean(np.log(pressure_ratio(fit.variant.system, loaded.info, opts))))
        b = log_ratio / lr if lr > 0 else math.nan
        if not (0.0 <= b <= 1.0):
            continue
        var = _with_preload(fit.variant, k, P)
        x = fit.x.copy()
        x[j] = b
        ev = diag.evaluate(var, x, fit.ev.index, jacobian=False)  # the misfit alone
        rows.append({"preload_N": P, "beta": b, "chi2": float(ev.r @ ev.r), "fitted": P == P0})
    return pd.DataFrame(rows)


def identifiable_text(ratios: pd.DataFrame, curve: pd.DataFrame | None, profile: dict | None,
                      beta: float, beta_ci: tuple, n_levels: int) -> str:
    """What the force levels identify of the contact law, in words (identifiable numbers first)."""
    parts = []
    for state, g in ratios.groupby("state", sort=False):
        lo, hi = float(g["stiffness_ratio"].min()), float(g["stiffness_ratio"].max())
        rng = f"{lo:.3f}" if abs(hi - lo) < 5e-4 else f"{lo:.3f}..{hi:.3f} over the carriages"
        parts.append(f"{state}/{g['reference_state'].iloc[0]} {rng} (95 % CI {g['ci95_low'].min():.3f} .. "
                     f"{g['ci95_high'].max():.3f})")
    dirs = ratios["directions"].iloc[0] if len(ratios) else "x,y"
    txt = f"joint stiffness ratio in {dirs}: " + "; ".join(parts) + "."
    if profile is None:
        pts = ", ".join(f"beta = {r.beta:.3f} at P = {r.preload_N:g} N" for r in curve.itertuples()
                        if r.preload_N in (0.0, 100.0, 400.0, 1600.0)) if curve is not None and len(curve) else ""
        spread = (f" (chi-square {curve['chi2'].min():.1f} .. {curve['chi2'].max():.1f} along the curve)"
                  if curve is not None and len(curve) else "")
        held = curve[curve["fitted"]] if curve is not None and len(curve) else None
        at = f" (the fit holds P at {held['preload_N'].iloc[0]:g} N)" if held is not None and len(held) else ""
        txt += (f" With {n_levels} force levels beta and the block preload P are not separately identifiable: "
                f"only this ratio is. Every pair on the curve fits alike{spread}: {pts}{at}.")
    else:
        hi = "inf" if math.isinf(profile["high"]) else f"{profile['high']:.0f}"
        txt += (f" With {n_levels} force levels the curvature of the law separates beta from the block "
                f"preload P: P = {profile['preload_N']:.0f} N (95 % profile interval {profile['low']:.0f} .. "
                f"{hi} N), beta = {beta:.3f} at that P (95 % over the P interval {profile['beta_low']:.3f} .. "
                f"{profile['beta_high']:.3f}).")
    return txt


def _beta_ci(fit: Fit, j: int) -> tuple[float, float]:
    sd = float(np.sqrt(max(fit.scaled_covariance()[j, j], 0.0)))
    b = float(fit.x[j])
    return max(b - 1.96 * sd, 0.0), min(b + 1.96 * sd, 1.0)


def profile_candidate(diag: Diagnoser, current: Fit, rows: list, fits: dict, alpha: float, log) -> None:
    """With three or more force levels, profile the block preload of the refitted em_preload
    candidate (:func:`profile_preload`): its fit and ranking row are replaced by the best P (P
    counted as a parameter)."""
    from jointid.diagnosis.results import refit_row

    if "+em_preload" not in fits or len(force_levels(diag.data)) < 3:
        return
    best, _, profile = profile_preload(diag, fits["+em_preload"], log)
    fits["+em_preload"] = best
    best.preload_profile = profile
    row = next(r[0] for r in rows if r[0]["effect"] == "em_preload")
    row.update(refit_row(best, current, diag.data, alpha, extra_params=1))
    row["ci95_low"], row["ci95_high"] = profile["beta_low"], profile["beta_high"]  # over the P interval
    row["note"] = f"block preload profiled: P = {profile['preload_N']:.0f} N"
    row["enable_with"] = f"em_preload: {{preload_N: {profile['preload_N']:.0f}}}"


def identify_preload(diag: Diagnoser, fit: Fit, log) -> tuple[str, pd.DataFrame]:
    """What the force levels identify of em_preload in ``fit`` ("" when it lacks the fitted effect).

    The stiffness ratios (:func:`stiffness_ratios`) and, with two force levels, the beta-P curve
    (:func:`preload_curve`); with three or more, the preload profile (:func:`profile_preload`, or
    the one already attached to ``fit`` by :func:`profile_candidate`).  Returns the sentence and the
    curve table.
    """
    n_levels = len(force_levels(diag.data))
    if _slot(fit.variant) is None or n_levels < 2:
        return "", pd.DataFrame()
    profile = getattr(fit, "preload_profile", None)
    if n_levels >= 3 and profile is None:
        fit, _, profile = profile_preload(diag, fit, log)
    j = _slot(fit.variant)[1]
    ci = _beta_ci(fit, j)
    ratios = stiffness_ratios(fit, diag.data, ci)
    curve = preload_curve(diag, fit) if profile is None else pd.DataFrame()
    return identifiable_text(ratios, curve, profile, float(fit.x[j]), ci, n_levels), curve


def identifiable_fits(diag: Diagnoser, current: Fit, fits: dict, ranking: pd.DataFrame, combos: pd.DataFrame,
                 log) -> tuple[dict, pd.DataFrame]:
    """Step 8 of the loop: what the data identify of a fitted em_preload (:func:`identify_preload`) in every fit the
    verdict may name: ``{fit label: sentence}`` (labels ``current``, ``+A``, ``+A+B``) and the beta-P
    curve of the first one."""
    labels = ["current"] + [f"+{n}" for n in ranking["effect"] if f"+{n}" in fits]
    if len(combos):
        labels += [f"+{e}" for e in combos[combos["explains"]]["effects"]]
    out, curve = {}, pd.DataFrame()
    for lab in labels:
        text, c = identify_preload(diag, current if lab == "current" else fits[lab], log)
        if text:
            out[lab] = text
            curve = c if curve.empty else curve
    if "+em_preload" in out:
        ranking.loc[ranking["effect"] == "em_preload", "identifiable"] = out["+em_preload"]
    return out, curve
