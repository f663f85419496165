"""Effects combined: forward selection and every pair of the leading candidates (docs/effects.md).

When no single library effect brings the model to the noise level, two effects may be missing at
once.  Before the verdict says "outside the library", :func:`combine_candidates` refits the
current model plus every pair of the ``n_combine`` leading refitted candidates (best AICc first, so
the forward-selection step — the best single plus each other — comes first), each from the two
single refits it continues, and keeps those whose chi-square is consistent with the noise.  The
leading pair is certified at its optimum (a Sturm count), as the leading single refit is.
"""

from __future__ import annotations

import itertools

import numpy as np

from jointid.diagnosis.fitting import Diagnoser, Fit, best_fit, refit
from jointid.diagnosis.statistics import score_candidate
from jointid.diagnosis.variants import EffectSpec
from jointid.progress import Steps

__all__ = ["combine_candidates", "combination_row", "continuation_starts", "refit_at", "refit_on_ladder"]


def continuation_starts(current: Fit, fa: Fit, fb: Fit) -> list[np.ndarray]:
    """Start vectors of ``current + a + b`` from the single refits ``fa`` (``current + a``) and ``fb``
    (``current + b``): each continued with the other effect at (almost) its null, so the pair never
    ends worse than either single."""
    p = current.variant.n_params
    ta, tb = fa.x[p:], fb.x[p:]
    na = np.array([pa.t_near_null() for _, pa in fa.variant.slots[len(current.variant.slots):]])
    nb = np.array([pb.t_near_null() for _, pb in fb.variant.slots[len(current.variant.slots):]])
    return [np.concatenate([fa.x[:p], ta, nb]), np.concatenate([fb.x[:p], na, tb])]


def combination_row(diag: Diagnoser, current: Fit, f: Fit, names: tuple, alpha: float) -> dict:
    """One row of ``combinations.csv``: the effects, their estimates, AICc against the current model,
    chi-square, p-value, whether it explains the data and the errors after."""
    summ = f.state_summary(diag.data)
    phys = f.variant.physical(f.x)
    est = "; ".join(f"{k} = {v:.4g}" for k, v in phys.items() if k.split(".")[0] in names)
    return {"effects": "+".join(names), "n_effects": len(names), "delta_aicc": f.aicc - current.aicc,
            "fit_chi2": f.chi2, "fit_p_value": f.p_value, "explains": bool(f.p_value >= alpha),
            "estimates": est,
            "max_abs_error_pct_after": max(s["max_abs_error_pct"] for s in summ if np.isfinite(s["max_abs_error_pct"])),
            "rms_error_pct_after": float(np.sqrt(np.nanmean([s["rms_error_pct"] ** 2 for s in summ])))}


def combine_candidates(diag: Diagnoser, current: Fit, singles: dict, n_combine: int, alpha: float,
                       log) -> tuple[list[dict], dict]:
    """Refit every pair of the ``n_combine`` best single refits (``singles``: effect name -> Fit).

    Returns the rows (:func:`combination_row`, sorted: explaining first, then by delta AICc) and the
    fits by label ``+a+b``.
    """
    lead = sorted(singles, key=lambda n: singles[n].aicc)[:n_combine]
    fits, names = {}, {}
    steps = Steps(len(lead) * (len(lead) - 1) // 2)
    for a, b in itertools.combinations(lead, 2):
        fa, fb = singles[a], singles[b]
        spec_b = fb.variant.effects[-1]
        var = fa.variant.extended(spec_b)
        log(f"diagnosis: refitting {current.variant.name} + {a} + {b} {steps.next()}")
        starts = continuation_starts(current, fa, fb)
        fits[f"+{a}+{b}"] = best_fit(diag.fit_starts(var, starts, index=fa.ev.index))
        names[f"+{a}+{b}"] = (a, b)
    if fits:  # the leading pair is a reported optimum (verdict, ladder): certified as the leading single
        lead_pair = min(fits, key=lambda k: fits[k].aicc)
        fits[lead_pair] = diag.certify(fits[lead_pair])
    rows = [combination_row(diag, current, f, names[k], alpha) for k, f in fits.items()]
    rows.sort(key=lambda r: (not r["explains"], r["delta_aicc"]))
    return rows, fits


def refit_at(diag: Diagnoser, fit: Fit, spec: EffectSpec) -> Fit:
    """``fit`` plus the candidate ``spec``, refitted from the starts its score test at ``fit`` gives
    (``fit`` re-evaluated on the present subspace first, as the candidate search does)."""
    ev = diag.evaluate(fit.variant, fit.x, fit.ev.index)
    at = Fit(fit.variant, ev, fit.pairings)
    st = score_candidate(diag, at, spec, np.zeros((0, len(ev.r))), {})
    return refit(diag, at, spec, st["t_hat"], verify=False)


def refit_on_ladder(diag: Diagnoser, rungs: list[Fit], current: Fit, spec: EffectSpec, *,
                    verify: bool = False) -> Fit:
    """``current + spec`` refitted as the pair it is: ``current`` is the top of a ladder of enabled
    effects and ``rungs`` the ladder's fits below it (bottom first); the candidate is refitted on
    the rung below (:func:`refit_at` on the bottom rung, this function above it) and that refit
    and ``current`` are continued with the other's effect at (almost) its null
    (:func:`continuation_starts`).

    This is the fit of the pair (last enabled effect + candidate) that a diagnosis without the last
    effect enabled makes, from the same starts: enabling the suggested effect, the next run's
    ranking of the other candidates is the last run's pairs, not a search of its own.  It never ends
    worse than ``current`` nor than the candidate on the rung below.
    """
    below = rungs[-1]
    fb = refit_at(diag, below, spec) if len(rungs) == 1 else refit_on_ladder(diag, rungs[:-1], below, spec)
    var = current.variant.extended(spec)
    best = best_fit(diag.fit_starts(var, continuation_starts(below, current, fb), index=current.ev.index))
    if verify:
        best = diag.certify(best)
    return best
