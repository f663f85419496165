"""The fitted reconstruction hypotheses compared: ranked by QAICc, broken fits listed apart, and the
answers over the admissible ones (the reconstruction ranges).

Reads the records of :func:`jointid.reconstruction.hypotheses.fit_hypothesis`.  The model error of the
comparison comes from its best ranked hypothesis (:mod:`jointid.identification.model_error`) and is
held fixed while all are judged (docs/reconstruction.md, "Hypotheses").
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from jointid.identification.model_error import ModelError, akaike_weights, estimate, from_chi2, qaicc

__all__ = ["CONFIDENCE_SET", "REJECT_ERROR_PCT", "RIGID_HZ", "admissible", "hypotheses_model_error", "rank_hypotheses",
           "reconstruction_ranges", "rejection"]

REJECT_ERROR_PCT = 50.0
"""A hypothesis whose fit leaves a measured mode (or a clearly visible model mode) more than this far
from its partner is a broken reading, not a competitor: it is listed apart, with the reason."""
RIGID_HZ = 1.0
"""A model mode below this frequency is a rigid-body mode: the hypothesis's fit is ill-posed."""
CONFIDENCE_SET = 0.95
"""The admissible hypotheses hold at least this much of the Akaike weight (:func:`admissible`)."""


def admissible(qaicc, delta: float = 4.0, *, level: float = CONFIDENCE_SET, axis: int = -1) -> np.ndarray:
    """Which hypotheses are admissible, given their QAICc along ``axis``: those within ``delta`` of the best,
    and the smallest set, best first, whose Akaike weights sum to at least ``level`` (a 95 % confidence set
    of models, Burnham & Anderson 2002, sec. 4.2).  The second part matters where two hypotheses are close
    and far from the rest: at delta 4.5 the second holds 10 % of the weight, and a range over the first
    alone would claim more certainty than the weights allow."""
    q = np.moveaxis(np.asarray(qaicc, float), axis, -1)
    d = q - q.min(axis=-1, keepdims=True)
    w = np.exp(-0.5 * d)
    w = w / w.sum(axis=-1, keepdims=True)
    order = np.argsort(d, axis=-1, kind="stable")
    ws = np.take_along_axis(w, order, axis=-1)
    inside = np.zeros(d.shape, bool)
    np.put_along_axis(inside, order, np.cumsum(ws, axis=-1) - ws < level, axis=-1)
    return np.moveaxis((d < delta) | inside, -1, axis)


def rejection(rec: dict) -> str:
    """Why a fitted hypothesis (:func:`fit_record`) cannot be ranked among the competitors, or "".

    ``ill-posed fit (a rigid-body mode at 0.0 Hz)`` when its model has a mode below :data:`RIGID_HZ`;
    ``rejected: ...`` when a measured mode has no partner within :data:`REJECT_ERROR_PCT` or a clearly
    visible model mode misses every measured one by more than that.
    """
    low = rec.get("lowest_freq_Hz")
    if low is not None and np.isfinite(low) and low < RIGID_HZ:
        return f"ill-posed fit (a rigid-body mode at {low:.1f} Hz)"
    why = []
    for s in rec["states"]:
        far = [str(i + 1) for i, e in enumerate(s.get("error_pct", []))
               if not np.isfinite(e) or abs(e) > REJECT_ERROR_PCT]
        if far:
            why.append(f"{s['state']} mode{'s' if len(far) > 1 else ''} {', '.join(far)} without a partner within "
                       f"{REJECT_ERROR_PCT:g} %")
    mis = [u for u in rec.get("unpaired_visible", []) if abs(u["misfit_pct"]) > REJECT_ERROR_PCT]
    if mis:
        why.append(f"{len(mis)} clearly visible model mode(s) more than {REJECT_ERROR_PCT:g} % from every measured one")
    return "rejected: " + "; ".join(why) if why else ""


def hypotheses_model_error(records: dict) -> ModelError:
    """The model error of the hypotheses' comparison: from the ranked (not rejected) hypothesis of least
    chi-square per degree of freedom (:func:`jointid.identification.model_error.estimate`)."""
    ok = [n for n in records if not rejection(records[n])] or list(records)
    dof = {n: records[n].get("dof", max(records[n]["n_data"] - records[n]["n_params"], 1)) for n in ok}
    name = min(ok, key=lambda n: (records[n]["chi2"] / dof[n], n))
    rec = records[name]
    r = rec.get("residuals")
    if r is None:  # a record written before the residuals were kept: one stated sigma assumed
        r, sig = [math.sqrt(rec["chi2"] / max(rec["n_data"], 1))] * rec["n_data"], 1.0
    else:
        sig = rec["residual_sigma_rel"]
    me = estimate(r, sig, rec["n_params"], reference=f"hypothesis {name}")
    if rec.get("shape_dof"):  # the shape rows: a block with its own model error (in units of their noise);
        # their rows move together within a mode and count as fewer (the diagnosis's design effect)
        shape = from_chi2(rec["shape_chi2"], rec["shape_dof"], float(rec.get("shape_sigma_rel") or 1.0),
                          reference=f"hypothesis {name}")
        me = replace(me, shape=replace(shape, design_effect=float(rec.get("shape_design_effect") or 1.0)))
    return me


def shape_chi2_total(rec: dict, me: ModelError) -> float:
    """The shape rows' chi-square of a hypothesis record at their noise plus the shape block's model error."""
    if not rec.get("shape_dof"):
        return 0.0
    return float(rec["shape_chi2"]) / (me.shape.inflation if me.shape is not None else 1.0)


TIE_QAICC = 1e-3
"""QAICc differences below this order hypotheses by their place in the configuration, not by QAICc: the fits
agree with each other only to the reduced solver's tolerance (chi-square about 1e-6 relative)."""


def rank_hypotheses(records: dict, *, delta: float = 4.0) -> tuple[list[dict], list[dict], ModelError]:
    """Rank fitted hypotheses (name -> :func:`fit_record` plus ``description``) by QAICc.

    The model error comes from the best ranked hypothesis (:func:`hypotheses_model_error`) and is held
    fixed; QAICc is then each hypothesis's chi-square at the stated noise plus that error, with the
    AICc penalty.  Hypotheses with a :func:`rejection` reason are listed after the ranked ones, with
    no rank, QAICc or weight, and the reason.

    Returns ``(ranking rows, spread rows, model error)``: per hypothesis rank, AICc at the stated noise,
    QAICc, delta QAICc, Akaike weight, chi-square, per-state max error and misfit count, joint
    parameters, beta and preload, and whether it is ``admissible`` (:func:`admissible`: within ``delta`` QAICc
    of the best, or in the 95 % confidence set of models); and per parameter the range of values and of 95 %
    intervals over the admissible hypotheses (the reconstruction range).
    """
    me = hypotheses_model_error(records)
    reasons = {n: rejection(records[n]) for n in records}
    q = {}
    for n, rec in records.items():
        if not reasons[n]:
            r = rec.get("residuals")
            chi2_m = rec["chi2"] / me.inflation if r is None else me.chi2_total(r, rec["residual_sigma_rel"])
            q[n] = qaicc(chi2_m + shape_chi2_total(rec, me), rec["n_data"] + int(rec.get("shape_dof") or 0),
                         rec["n_params"])
    # QAICc within TIE_QAICC of another is a tie (far below what the fits resolve): the one listed first wins
    order = {n: i for i, n in enumerate(records)}
    names = sorted(q, key=lambda n: (round(q[n] / TIE_QAICC), order[n]))
    best = min(q.values()) if names else float("nan")
    w = akaike_weights([q[n] for n in names])
    rows = []
    for rank, n in enumerate(names + sorted(n for n in records if reasons[n]), start=1):
        rec = records[n]
        ranked = n in q
        row = {"rank": rank if ranked else None, "hypothesis": n, "description": rec.get("description", ""),
               "aicc": rec["aicc"], "qaicc": q.get(n, float("nan")),
               "delta_qaicc": q[n] - best if ranked else float("nan"),
               "weight": float(w[names.index(n)]) if ranked else float("nan"),
               "chi2": rec["chi2"], "n_data": rec["n_data"], "n_params": rec["n_params"],
               "c_hat": me.c_hat, "sigma_model_pct": 100 * me.sigma_model_rel, "listed_apart": reasons[n],
               "certified": bool(rec.get("certified", True))}  # Sturm-counted at its optimum (older records: all)
        for s in rec["states"]:
            row[f"max_abs_error_{s['state']}_pct"] = s["max_abs_error_pct"]
            row[f"unpaired_visible_{s['state']}"] = s["n_unpaired_visible"]
        for p in rec["parameters"]:
            row[p["parameter"]] = p["value"]
        row["preload_N"] = rec.get("preload_N")
        rows.append(row)
    keep = dict(zip(names, admissible([q[n] for n in names], delta))) if names else {}
    for row in rows:
        row["admissible"] = bool(keep.get(row["hypothesis"], False))
    admissible_names = [n for n in names if keep[n]]
    spread = {}
    for n in admissible_names:
        for p in records[n]["parameters"]:
            s = spread.setdefault(p["parameter"], {"parameter": p["parameter"], "values": [], "lo": [], "hi": [],
                                                   "hypotheses": [], "weights": []})
            s["values"].append(p["value"])
            s["lo"].append(p["ci95_low"])
            s["hi"].append(p["ci95_high"])
            s["hypotheses"].append(n)
            s["weights"].append(float(w[names.index(n)]))
    out = []
    for s in spread.values():
        ww = np.array(s["weights"]) / max(sum(s["weights"]), 1e-300)
        out.append({"parameter": s["parameter"], "n_hypotheses": len(s["values"]),
                    "hypotheses": " ".join(s["hypotheses"]), "value_min": min(s["values"]),
                    "value_max": max(s["values"]),
                    "value_weighted": float(np.dot(ww, s["values"])),
                    "combined_ci95_low": min(s["lo"]), "combined_ci95_high": max(s["hi"])})
    return rows, out, me


def admissible_rows(rows: list[dict], delta: float = 4.0) -> list[dict]:
    """The ranked rows of :func:`rank_hypotheses` that are admissible (its ``admissible`` column; rows written
    before it: within ``delta`` of the best)."""
    ranked = [r for r in rows if r.get("rank") is not None and not _nan(r.get("rank"))
              and np.isfinite(r["delta_qaicc"])]
    if all("admissible" in r for r in ranked):
        return [r for r in ranked if r["admissible"]]
    return [r for r in ranked if r["delta_qaicc"] < delta]


def _nan(v) -> bool:
    return isinstance(v, float) and math.isnan(v)


def reconstruction_ranges(records: dict, rows: list[dict], *, delta: float = 4.0) -> list[dict]:
    """The answers over the admissible reconstructions (``rows`` from :func:`rank_hypotheses`, its
    ``admissible`` column).

    One row per quantity and state (and mode): ``quantity``, ``state``, ``mode`` (0: none), ``unit``,
    ``value_min``, ``value_max``, ``value_weighted`` (Akaike weights of QAICc, renormalised over the
    admissible set), ``n_hypotheses``, ``hypotheses``.  Quantities: each joint stiffness per area in
    each state (``N_per_m3``) and its change from the first state to each other (``pct``), Table 1's
    dynamic-stiffness minimum per state (``N_per_m``) and its change, and per measured mode the
    model frequency (``Hz``) and its error (``pct``) of Tables 2-3.
    """
    adm = admissible_rows(rows, delta)
    if not adm:
        return []
    names = [r["hypothesis"] for r in adm]
    w = np.array([r["weight"] for r in adm], float)
    w = w / w.sum() if w.sum() > 0 else np.full(len(w), 1 / len(w))
    values: dict[tuple, list] = {}

    def put(key, name, v):
        if v is not None and np.isfinite(v):
            values.setdefault(key, []).append((name, float(v)))

    for n in names:
        states = records[n]["states"]
        first = states[0]
        for st in states:
            for par, v in st["joints_N_per_m3"].items():
                put((par, st["state"], 0, "N_per_m3"), n, v)
                if st is not first and first["joints_N_per_m3"].get(par):
                    put((f"{par} change from {first['state']}", st["state"], 0, "pct"), n,
                        100 * (v / first["joints_N_per_m3"][par] - 1))
            k = (st.get("dynamic_stiffness") or {}).get("k_min_N_per_m")
            put(("table1_k_dyn_min", st["state"], 0, "N_per_m"), n, k)
            k0 = (first.get("dynamic_stiffness") or {}).get("k_min_N_per_m")
            if st is not first and k and k0:
                put((f"table1_k_dyn_min change from {first['state']}", st["state"], 0, "pct"), n, 100 * (k / k0 - 1))
            for i, (fm, e) in enumerate(zip(st["f_model_Hz"], st["error_pct"]), start=1):
                put(("model_freq", st["state"], i, "Hz"), n, fm)
                put(("error", st["state"], i, "pct"), n, e)
    out = []
    for (q, state, mode, unit), vals in values.items():
        who = [a for a, _ in vals]
        v = np.array([b for _, b in vals])
        ww = np.array([w[names.index(a)] for a in who])
        out.append({"quantity": q, "state": state, "mode": mode, "unit": unit, "value_min": float(v.min()),
                    "value_max": float(v.max()), "value_weighted": float(ww @ v / ww.sum()),
                    "n_hypotheses": len(v), "hypotheses": " ".join(who)})
    return out
