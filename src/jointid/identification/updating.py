"""Response-surface model updating: surfaces over the DOE, identification per state, FE verification.

Stages (each reads and writes files, see ``jointid.stages`` for the workflow wiring):

1. :func:`fit_surfaces` — track the modes through the DOE by MAC, fit one surface per tracked mode
   to ``ln f`` over the coded log-parameters, and check it at fresh verification points solved by FE.
2. :func:`identify_state` — pair measured and tracked modes (MAC when shapes are measured, else
   order-preserving frequency assignment, re-paired at each optimum until stable), then bounded
   multi-start least squares on the weighted relative frequency error.
3. :func:`verify_state` — re-solve the full FE model at the optimum and report FE, surface and
   measured frequencies side by side (the table values are the FE ones).
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from jointid.identification.doe import to_coded, to_physical
from jointid.errors import DataError, NumericalWarning
from jointid.identification.identify import identify
from jointid.identification.surface import Surface, fit_surface
from jointid.identification.surface_checks import diagnostics
from jointid.identification.ties import choose_tied, hiding_peak, least_cost_tied, paired_ss
from jointid.correlate.pairing import pair_by_frequency, pair_by_shapes
from jointid.identification.tracking import track_doe


class LogFrequencyModel:
    """Natural frequencies ``exp(surface(x))`` of the tracked modes, with their Jacobian."""

    def __init__(self, surface: Surface, select: np.ndarray | None = None):
        self.surface = surface
        self.select = select

    def __call__(self, x):
        f = np.exp(self.surface(np.asarray(x, float)))
        return f if self.select is None else f[self.select]

    def jacobian(self, x):
        x = np.asarray(x, float)
        f = np.exp(self.surface(x))
        J = f[:, None] * self.surface.jacobian(x)
        return J if self.select is None else J[self.select]


# ------------------------------------------------------------------ 1. surfaces
def fit_surfaces(sheet: pd.DataFrame, freqs: np.ndarray, shapes: np.ndarray, descriptions: np.ndarray,
                 names: list[str], band_Hz: tuple[float, float], kind: str = "quadratic"):
    """Track modes through the DOE and fit one surface per tracked mode.

    Returns ``(surface_doc, diagnostics DataFrame)``; ``surface_doc`` is JSON-serialisable.
    """
    X = sheet[[f"x_{n}" for n in names]].to_numpy()
    design = (sheet["role"] == "design").to_numpy()
    ref = int(np.argmin(np.where(design, np.abs(X).sum(axis=1), np.inf)))
    ref_modes, tf, tm = track_doe(freqs, shapes, ref, band_Hz)
    lost = np.isnan(tf[design]).any(axis=0)
    keep = np.flatnonzero(~lost)
    if len(keep) == 0:
        raise DataError("surface: no mode could be tracked through the whole DOE — narrow the "
                        "joints.parameters bounds or raise solver.n_modes")
    Y = np.log(tf[design][:, keep])
    surf = fit_surface(X[design], Y, kind=kind)
    diag = diagnostics(surf, X[design], Y).reset_index(drop=True)
    verify = ~design & ~np.isnan(tf[:, keep]).any(axis=1)
    rows = []
    for col, r in enumerate(keep):
        row = {"tracked_mode": int(r + 1), "ref_freq_Hz": float(freqs[ref, ref_modes[r]]),
               "description": str(descriptions[ref][ref_modes[r]]),
               "min_mac_in_doe": float(tm[design, r].min())}
        row.update({k: float(diag.loc[col, k]) for k in ("r2", "r2_adj", "r2_pred", "rmse")})
        if verify.any():
            pred = np.exp(surf.predict(X[verify])[:, col])
            err = 100 * np.abs(pred - tf[verify, r]) / tf[verify, r]
            row["verify_max_error_pct"] = float(err.max())
        else:
            row["verify_max_error_pct"] = float("nan")
        rows.append(row)
    for r in np.flatnonzero(lost):
        rows.append({"tracked_mode": int(r + 1), "ref_freq_Hz": float(freqs[ref, ref_modes[r]]),
                     "description": str(descriptions[ref][ref_modes[r]]) + " (lost in DOE: not fitted)",
                     "min_mac_in_doe": float(np.nanmin(tm[design, r]))})
    diag_df = pd.DataFrame(rows)
    doc = {"names": names, "kind": kind, "ref_point": str(sheet["point"].iloc[ref]),
           "tracked_modes": [int(r + 1) for r in keep],
           "ref_freqs_Hz": [float(freqs[ref, ref_modes[r]]) for r in keep],
           "descriptions": [str(descriptions[ref][ref_modes[r]]) for r in keep],
           "ref_shapes": shapes[ref][:, ref_modes[keep]].tolist(),
           "surface": surf.to_dict()}
    return doc, diag_df


# ------------------------------------------------------------------ 2. identification
def state_misfits(full, rule, ref_shapes, f_meas, pairing, x) -> tuple[np.ndarray, np.ndarray]:
    """``(modes, targets)``: the tracked modes the test would clearly have seen that ``pairing`` leaves
    unpaired at the coded point ``x`` (the surface ``full``), and the frequency each is scored against;
    empty without a visibility ``rule``."""
    if rule is None:
        return np.zeros(0, int), np.zeros(0)
    f = full(x)
    return rule.misfits(pairing, f, rule.visibility(ref_shapes, f), f_meas)


def identify_state(doc: dict, f_meas: np.ndarray, lower: np.ndarray, upper: np.ndarray, *,
                   meas_shapes: np.ndarray | None = None, weights=None, n_starts: int = 16,
                   seed: int = 0, sigma_rel: float = 0.01, pairing=None, candidates: list | None = None,
                   rule=None, damping=None, decision: dict | None = None, memo: dict | None = None):
    # many parameters: the surface fit's options (shapes, weights, starts, pairing, rule, damping), keyword with defaults
    # long: four closures share the surface, the data and the rule (misfits, fit, run, pair); the body is the multistart
    """Identify the joint parameters of one state from measured frequencies.

    Returns ``(result, pairing, warnings list)`` where ``pairing[i]`` is the column of the tracked
    mode paired with measured mode ``i``.  A given ``pairing`` is kept as it is; otherwise it comes
    from the measured shapes (MAC) or, for frequencies alone, from the best of several starts, each
    re-paired by frequency until stable.  ``candidates`` (a list) collects ``(pairing, cost)`` of
    every start in that last case.  ``rule`` (:class:`jointid.identification.visibility.VisibilityRule`,
    its labels those of ``doc["ref_shapes"]``): tracked modes the test would clearly have seen and
    that no measured mode takes are misfits, extra residuals of the fit (``result.residuals`` beyond
    the measured modes), and the frequency pairing pays for leaving them unpaired; the swaps of such a
    mode with the partner of the measured mode it is scored against fit exactly alike, so the
    multistart's winner is compared with them (:func:`misfit_swaps`) and the tie rules choose
    (:func:`jointid.identification.ties.choose_tied`): with ``damping`` (the damping ratio of each
    measured mode, :func:`jointid.identification.ties.tie_damping`) the pairing whose unpaired visible
    modes could all hide in a measured peak's half-power band, else the nearest partners.
    ``decision`` (a dict) receives the rule that decided and the tied pairings' unpaired visible modes
    (:func:`tie_record`).  ``memo`` (a dict, kept by the caller across calls for the same state and
    options) holds every multistart fit by its pairing and misfit set: a fit asked again is not run again
    (it is a function of those alone, so the answer is the same).
    """
    surf = Surface.from_dict(doc["surface"])
    names = doc["names"]
    full = LogFrequencyModel(surf)
    n_track = len(doc["tracked_modes"])
    if len(f_meas) > n_track:
        raise DataError(f"measurement: {len(f_meas)} measured modes but only {n_track} model modes are "
                        "tracked in the band — raise solver.n_modes or widen the tracked band")
    ref_shapes = np.asarray(doc["ref_shapes"]) if (rule is not None or meas_shapes is not None) else None
    caught: list[str] = []

    def misfits(pairing, x):
        return state_misfits(full, rule, ref_shapes, f_meas, pairing, x)

    def fit(pairing, pen, tgt):
        if memo is None:
            return _fit(pairing, pen, tgt)
        key = (tuple(int(c) for c in pairing), tuple(int(c) for c in pen), np.asarray(tgt, float).tobytes())
        if key not in memo:
            memo[key] = _fit(pairing, pen, tgt)
        return memo[key]

    def _fit(pairing, pen, tgt):
        model = LogFrequencyModel(surf, pairing)
        extra = extra_jac = None
        if pen.size:  # the unpaired visible modes: their distance to the nearest measured mode
            extra = lambda x: (full(x)[pen] - tgt) / tgt  # noqa: E731
            extra_jac = lambda x: full.jacobian(x)[pen] / tgt[:, None]  # noqa: E731
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always", NumericalWarning)
            res = identify(model, f_meas, weights=weights, jacobian=model.jacobian, n_starts=n_starts,
                           seed=seed, sigma_rel=sigma_rel, names=names, lower=lower, upper=upper, extra=extra,
                           extra_jacobian=extra_jac)
        return res, [str(x.message) for x in w]

    def run(pairing, x_hint=None):
        pen, tgt = misfits(pairing, np.zeros(len(names)) if x_hint is None else x_hint)
        for _ in range(4):  # the misfit set at the optimum it gives, until it repeats
            res, msgs = fit(pairing, pen, tgt)
            new_pen, new_tgt = misfits(pairing, res.x_coded)
            if np.array_equal(new_pen, pen) and np.allclose(new_tgt, tgt):
                break
            pen, tgt = new_pen, new_tgt
        return res, msgs

    def pair(x):
        if rule is None:
            return pair_by_frequency(f_meas, full(x))
        f = full(x)
        return rule.pair_by_frequency(f_meas, f, rule.visibility(ref_shapes, f), np.arange(n_track))

    if pairing is not None:
        pairing = np.asarray(pairing, int)
        res, caught = run(pairing)
        return res, pairing, caught
    if meas_shapes is not None:
        pairing, macs = pair_by_shapes(meas_shapes, ref_shapes)
        if np.any(pairing < 0):
            bad = ", ".join(str(i + 1) for i in np.flatnonzero(pairing < 0))
            raise DataError(f"measurement: measured mode(s) {bad} have no model mode with MAC >= 0.5 — "
                            "check the shapes or the model")
        res, caught = run(pairing)
        return res, pairing, caught
    rng = np.random.default_rng(seed)
    k = len(names)
    starts = np.vstack([np.zeros(k), rng.uniform(-1, 1, size=(8, k))])
    best = None
    for x0 in starts:
        pairing = pair(x0)
        for _ in range(10):
            res, msgs = run(pairing, x0 if rule is not None else None)
            new = pair(res.x_coded)
            if np.array_equal(new, pairing):
                break
            pairing = new
        if candidates is not None:
            candidates.append((tuple(int(c) for c in pairing), float(res.cost)))
        if best is None or res.cost < best[0].cost - 1e-12:
            best = (res, pairing, msgs)
    if rule is not None:  # the winner's tied swaps (see identify_states_jointly): the tie rules choose
        options = [best]
        for q in misfit_swaps(doc, best[1], best[0].x_coded, f_meas, rule):
            res_q, msgs_q = run(np.asarray(q), best[0].x_coded)
            options.append((res_q, np.asarray(q), msgs_q))
        hidden = {id(o): unpaired_visible(doc, o[1], o[0].x_coded, f_meas, rule, damping) for o in options}
        best, how = choose_tied(options, lambda o: o[0].cost, lambda o: paired_ss(o[0], f_meas), lambda o: o[1],
                                None if damping is None else lambda o: all(m["hides"] for m in hidden[id(o)]))
        if decision is not None:
            tied = least_cost_tied(options, lambda o: o[0].cost)
            decision.update(tie_record(how, [(o[1], hidden[id(o)]) for o in tied]))
    return best


def unpaired_visible(doc: dict, pairing, x, f_meas: np.ndarray, rule, damping=None, state=None) -> list[dict]:
    """The clearly visible tracked modes ``pairing`` leaves unpaired at the coded point ``x`` (the
    surfaces of ``doc``), each with the measured peak it comes nearest to hiding in
    (:func:`jointid.identification.ties.hiding_peak`, at the damping ratios ``damping`` of the measured
    modes; without them ``hides`` is None): records ``tracked_mode`` (1-based, as ``doc`` numbers
    them), ``freq_Hz``, ``measured_order``, ``measured_Hz``, ``offset_pct`` (signed, model minus
    measured), ``damping_ratio``, ``hides``, ``offset_nearest_pct`` (unsigned, to the nearest measured
    mode) (and ``state`` if given)."""
    full = LogFrequencyModel(Surface.from_dict(doc["surface"]))
    ref = np.asarray(doc["ref_shapes"]) if rule is not None else None
    cols, _ = state_misfits(full, rule, ref, f_meas, np.asarray(pairing, int), x)
    f = full(x)
    out = []
    for j in cols:
        rec = {"tracked_mode": int(doc["tracked_modes"][j]), "freq_Hz": float(f[j])}
        peak = hiding_peak(f[j], f_meas, 1.0 if damping is None else damping)
        rec.update(measured_order=peak["measured_order"], measured_Hz=peak["measured_Hz"],
                   offset_pct=100 * float(f[j] / peak["measured_Hz"] - 1),
                   damping_ratio=None if damping is None else peak["damping_ratio"],
                   hides=None if damping is None else peak["hides"],
                   offset_nearest_pct=100 * float(np.min(np.abs(f[j] / np.asarray(f_meas, float) - 1))))
        out.append(rec if state is None else {"state": state, **rec})
    return out


def tie_record(rule_text: str, tied: list) -> dict:
    """``params.json``'s record of a choice among tied pairings: ``rule`` (in words, see
    :func:`jointid.identification.ties.choose_tied`) and per tied pairing, in the order of the pairings
    (``tied``: ``(pairing, unpaired visible records)``), its ``pairing``, whether it is ``resolvable`` (every unpaired visible
    mode hides in a measured peak; None without damping ratios), its ``unpaired_visible`` modes and
    ``damping_ratio_needed``: the least damping ratio, alike for every measured mode, under which all
    of them could hide (0 when there is none)."""
    rows = []
    for pairing, seen in tied:
        known = all(m["hides"] is not None for m in seen)
        rows.append({"pairing": [int(c) for c in pairing], "unpaired_visible": seen,
                     "resolvable": bool(all(m["hides"] for m in seen)) if known else None,
                     "damping_ratio_needed": max((m["offset_nearest_pct"] / 100 for m in seen), default=0.0)})
    rows.sort(key=lambda r: r["pairing"])  # their costs are equal to round-off: the order must not follow them
    return {"rule": rule_text, "tied": rows}


def identify_states_jointly(doc: dict, f_meas: dict, lower, upper, **kw) -> tuple[np.ndarray, dict]:
    """One pairing of measured and tracked modes for several frequency-only states.

    Measured mode ``i`` is taken to be the same physical mode in every state (the convention of a
    dataset that lists the states' modes side by side, as the paper's Tables 2 and 3 do), so all
    states pair it with the same tracked mode.  Each state is identified with every pairing that a
    start of any state converged to; the pairing of least summed cost wins.  Without that rule, with
    model modes inside the band that the test did not see, a state can prefer a pairing that another
    state rules out.  A clearly visible tracked mode left unpaired costs its distance to the measured
    mode it is scored against, exactly what pairing it with that mode would cost: every swap of the
    best pairings (:func:`misfit_swaps`) is tried too, and among tied pairings the nearest partners win.

    ``f_meas`` maps state -> measured frequencies (equal counts); ``kw`` as :func:`identify_state`
    (``sigma_rel`` and ``rule`` may be mappings state -> value).  Returns ``(pairing, info)``: the summed-cost
    winner; ``info[state]`` its cost there and the state's own best pairing; ``info["candidates"]``
    every pairing tried with its summed cost and chi-square (``sum cost / sigma^2``), best first;
    ``info["tie_rule"]`` the rule that chose among the pairings tied with the winner
    (:func:`tie_record`).  ``damping`` (a mapping state -> damping ratio of each measured mode, or
    None) lets the resolvability rule choose among tied pairings: the one whose unpaired visible modes
    could all hide, in every state, inside a measured peak's half-power band.
    """
    sig = kw.pop("sigma_rel", 0.01)
    sigma = sig if isinstance(sig, dict) else {s: sig for s in f_meas}
    vr = kw.pop("rule", None)
    rules = vr if isinstance(vr, dict) else {s: vr for s in f_meas}
    dmp = kw.pop("damping", None)
    damping = {s: None if dmp is None else dmp.get(s) for s in f_meas}
    cands, own = {}, {}
    memos = {s: {} for s in f_meas}  # each state's fits by pairing and misfit set (identify_state)
    for state, f in f_meas.items():
        found: list = []
        _, p, _ = identify_state(doc, np.asarray(f, float), lower, upper, sigma_rel=sigma[state],
                                 candidates=found, rule=rules[state], damping=damping[state], memo=memos[state], **kw)
        own[state] = tuple(int(c) for c in p)
        for pairing, _ in found:
            cands.setdefault(pairing, None)
        # the state's own best pairing is a candidate too, whether or not its search listed it (with a
        # visibility rule it may not be: identify.pairing: independent then had no cost for it)
        cands.setdefault(own[state], None)
    tried, fits, queue = [], {}, sorted(cands)
    for _ in range(4):  # the pairings the starts found, then the swaps of the best, until none is new
        for pairing in queue:
            fits[pairing] = {s: identify_state(doc, np.asarray(f, float), lower, upper, sigma_rel=sigma[s],
                                               pairing=pairing, rule=rules[s], memo=memos[s], **kw)[0]
                             for s, f in f_meas.items()}
            costs = {s: r.cost for s, r in fits[pairing].items()}
            tried.append({"pairing": list(pairing), "cost": sum(costs.values()),
                          "chi2": sum(c / sigma[s] ** 2 for s, c in costs.items()), "costs": costs,
                          "chi2_by_state": {s: c / sigma[s] ** 2 for s, c in costs.items()},
                          "paired_ss": sum(paired_ss(r, f_meas[s]) for s, r in fits[pairing].items())})
        swaps = {q for t in least_cost_tied(tried, lambda t: t["cost"]) for s, r in fits[tuple(t["pairing"])].items()
                 for q in misfit_swaps(doc, t["pairing"], r.x_coded, np.asarray(f_meas[s], float), rules[s])}
        queue = sorted(swaps - set(fits))
        if not queue:
            break
    tied = least_cost_tied(tried, lambda t: t["cost"])
    seen = {tuple(t["pairing"]): [m for s, r in fits[tuple(t["pairing"])].items() for m in unpaired_visible(
        doc, t["pairing"], r.x_coded, np.asarray(f_meas[s], float), rules[s], damping[s], state=s)] for t in tied}
    known = all(d is not None for d in damping.values())
    win, how = choose_tied(tried, lambda t: t["cost"], lambda t: t["paired_ss"], lambda t: t["pairing"],
                           (lambda t: all(m["hides"] for m in seen[tuple(t["pairing"])])) if known else None)
    info = {s: {"cost": win["costs"][s], "own": list(own[s])} for s in f_meas}
    info["candidates"] = sorted(tried, key=lambda t: (t["cost"], t["paired_ss"], t["pairing"]))
    info["tie_rule"] = tie_record(how, [(t["pairing"], seen[tuple(t["pairing"])]) for t in tied])
    return np.asarray(win["pairing"], int), info


def misfit_swaps(doc: dict, pairing, x, f_meas: np.ndarray, rule) -> list[tuple]:
    """Pairings that give a measured mode the clearly visible, unpaired tracked mode scored against it
    (at the coded point ``x``) in place of its partner, the order of the modes kept.

    Such a swap fits about as well as ``pairing`` (the two modes change roles, paired and misfit,
    against the same measured frequency), so which of the two a multistart finds first is round-off;
    both are compared.
    """
    full = LogFrequencyModel(Surface.from_dict(doc["surface"]))
    ref = np.asarray(doc["ref_shapes"]) if rule is not None else None
    cols, targets = state_misfits(full, rule, ref, f_meas, pairing, x)
    out = []
    p = [int(c) for c in pairing]
    for u, t in zip(cols, targets):
        for i in np.flatnonzero(np.abs(f_meas - t) <= 1e-9 * t):  # scored against measured mode i
            q = p[:i] + [int(u)] + p[i + 1:]
            if all(a < b for a, b in zip(q, q[1:])):
                out.append(tuple(q))
    return out


# ------------------------------------------------------------------ 3. verification
def verify_pairing(doc: dict, pairing: np.ndarray, fe_shapes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """FE mode index for each paired tracked mode, by MAC with the tracked reference shapes."""
    ref_shapes = np.asarray(doc["ref_shapes"])[:, pairing]
    index, macs = pair_by_shapes(ref_shapes, fe_shapes, threshold=0.3)
    return index, macs


def coded(theta: dict, names: list[str], lower, upper) -> np.ndarray:
    return to_coded(np.array([theta[n] for n in names]), lower, upper)


def physical(x, lower, upper) -> np.ndarray:
    return to_physical(np.asarray(x, float), lower, upper)
