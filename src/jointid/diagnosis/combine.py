"""Effects combined: forward selection and every pair of the leading candidates (docs/effects.md).

When no single library effect brings the model to the noise level, two effects may be missing at
once.  Before the verdict says "outside the library", :func:`combine_candidates` refits the
current model plus every pair of the ``n_combine`` leading refitted candidates (best AICc first, so
the forward-selection step — the best single plus each other — comes first), each from the two
single refits it continues, and keeps those whose chi-square is consistent with the noise.
"""

from __future__ import annotations

import itertools

import numpy as np

from jointid.diagnosis.fitting import Diagnoser, Fit, best_fit
from jointid.progress import Steps

__all__ = ["combine_candidates", "combination_row"]


def _starts(current: Fit, fa: Fit, fb: Fit) -> list[np.ndarray]:
    """Start vectors of ``current + a + b``: each single refit continued with the other effect at
    (almost) its null, so the pair never ends worse than either single."""
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
    rows, fits = [], {}
    steps = Steps(len(lead) * (len(lead) - 1) // 2)
    for a, b in itertools.combinations(lead, 2):
        fa, fb = singles[a], singles[b]
        spec_b = fb.variant.effects[-1]
        var = fa.variant.extended(spec_b)
        log(f"diagnosis: refitting {current.variant.name} + {a} + {b} {steps.next()}")
        best = best_fit([diag.fit(var, x0, index=fa.ev.index) for x0 in _starts(current, fa, fb)])
        fits[f"+{a}+{b}"] = best
        rows.append(combination_row(diag, current, best, (a, b), alpha))
    rows.sort(key=lambda r: (not r["explains"], r["delta_aicc"]))
    return rows, fits
