"""The measurement that would narrow the reconstruction (docs/reconstruction.md, same title).

Several hypotheses are admissible (within ΔQAICc 4 of the best, or in the 95 % confidence set of models:
:func:`jointid.reconstruction.ranking.admissible`), and their joint parameters differ.  For
each candidate measurement this module asks: if one admissible hypothesis were the truth and the
measurement were made, which hypotheses would stay admissible, and how wide would the range of the
joint parameters over them be?

Each hypothesis's record predicts the candidates (:mod:`jointid.reconstruction.predictions`):

* the weight of the moving part (``moving_mass_kg``), at ``weight_uncertainty_pct``;
* the static drive-point stiffness per state and direction, at ``static_stiffness_uncertainty_pct`` and
  twice the frequency block's model error (a stiffness goes as the square of a frequency);
* the shape of the measured modes at one DOF pair of a state measured without shapes, at
  ``shape_uncertainty_pct`` of the pair's RMS per DOF: one degree of freedom per mode that moves the pair,
  the ratio of the two displacements (:mod:`jointid.diagnosis.shape_proposal`).  The pair is the one of
  least expected range (noise-free, below).

With hypothesis ``g`` as the truth, a scalar measurement ``y = y_g (1 + s e)``, ``e ~ N(0, 1)``, adds to
every hypothesis ``h`` the chi-square ``(y - y_h)^2 / (s y_g)^2``; a DOF pair adds, per mode, the squared
component of the measured pair ``u_g + eps e`` (``u_g`` at unit RMS over the pair) across ``h``'s direction,
over ``eps^2``.  Each hypothesis's QAICc grows by its chi-square; the hypotheses admissible after it (within
``delta`` of the new best, or in the 95 % confidence set of models: :func:`jointid.reconstruction.ranking.admissible`)
stay, and a joint parameter's range over them is ``max / min`` (1 for one survivor).
The expected gain averages over :attr:`ProposalOptions.n_draws` noise draws (seeded; 0: the noise-free
measurement, ``e = 0``, whose chi-square is ``(y_g - y_h)^2 / sigma^2``) and over the truths weighted
by their Akaike weights renormalised over the admissible set.  The joint parameters are those of
today's fits (a refit with the new measurement would move each within its interval).

No damping ratio is proposed: the hypotheses share one nominal modal damping ratio.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from jointid.config.hypotheses import ProposalOptions
from jointid.diagnosis.shape_proposal import VISIBLE_RMS, pair_chi2, pair_text
from jointid.reconstruction.ranking import admissible, admissible_rows

__all__ = ["ProposalOptions", "ScalarCandidate", "ShapePairCandidate", "expected_gain", "propose",
           "next_measurement_markdown", "COLUMNS"]


@dataclass
class _Candidate:
    """What every candidate measurement has: its name, kind, state, unit, relative 1-sigma noise and the
    hypotheses' predictions."""

    measurement: str
    kind: str
    state: str
    unit: str
    rel: float
    values: dict


@dataclass
class ScalarCandidate(_Candidate):
    """One scalar measurement: each hypothesis's prediction (``values``, in ``unit``) and the relative
    1-sigma uncertainty ``rel`` of the measured value."""

    def noise_shape(self, n: int) -> tuple:
        return (n,)

    def chi2(self, truth: str, names: list[str], e: np.ndarray) -> np.ndarray:
        """``(n_draws, n_hypotheses)`` chi-square each hypothesis adds when ``truth`` holds and the noise
        draws are ``e`` (``(n_draws,)``, standard normal; zeros: the noise-free measurement)."""
        yg = float(self.values[truth])
        s = self.rel * abs(yg)
        y = yg + s * np.asarray(e, float)
        yh = np.array([float(self.values[n]) for n in names])
        return ((y[:, None] - yh[None, :]) / s) ** 2

    def predictions_text(self, names: list[str]) -> str:
        return "; ".join(f"{n} {self.values[n]:.4g} {self.unit}" for n in names)


@dataclass
class ShapePairCandidate(_Candidate):
    """The shapes of the measured modes at one DOF pair: per hypothesis the pair's displacements
    ``(2, n_modes)`` from shapes at unit RMS over all measuring DOFs; ``eps`` the shape noise per DOF
    as a fraction of the pair's RMS."""

    def noise_shape(self, n: int) -> tuple:
        m = next(iter(self.values.values())).shape[1]
        return (n, 2, m)

    def chi2(self, truth: str, names: list[str], e: np.ndarray) -> np.ndarray:
        """As :meth:`ScalarCandidate.chi2`; ``e`` is ``(n_draws, 2, n_modes)``.  Modes that barely move
        the pair in the truth (RMS there below :data:`~jointid.diagnosis.shape_proposal.VISIBLE_RMS` of the
        mode's) add nothing, as in :func:`~jointid.diagnosis.shape_proposal.pair_chi2`."""
        a = np.asarray(self.values[truth], float)
        na = (a ** 2).sum(axis=0)
        seen = na >= 2 * VISIBLE_RMS ** 2
        u = a / np.sqrt(np.where(na > 0, na, 1.0) / 2)  # unit RMS over the pair
        y = u[None] + self.rel * np.asarray(e, float)  # (D, 2, M)
        out = np.zeros((y.shape[0], len(names)))
        for k, n in enumerate(names):
            b = np.asarray(self.values[n], float)
            nb = np.sqrt((b ** 2).sum(axis=0))
            ok = seen & (nb > 0)
            bh = b / np.where(nb > 0, nb, 1.0)
            cross = y[:, 0, :] * bh[1][None] - y[:, 1, :] * bh[0][None]
            out[:, k] = (np.where(ok[None], cross, 0.0) ** 2).sum(axis=1) / self.rel ** 2
        return out

    def predictions_text(self, names: list[str]) -> str:
        """Per hypothesis the displacements at the pair's two DOFs, mode by mode (:func:`pair_text`)."""
        return "; ".join(f"{n} {pair_text(*np.asarray(self.values[n], float))}" for n in names)


def _ranges(keep: np.ndarray, values: dict) -> dict:
    """``max / min`` of each parameter over the kept hypotheses, per draw (``keep``: (D, H))."""
    out = {}
    for p, v in values.items():
        v = np.asarray(v, float)[None, :]
        hi = np.where(keep, v, -np.inf).max(axis=1)
        lo = np.where(keep, v, np.inf).min(axis=1)
        out[p] = hi / lo
    return out


def expected_gain(cand, names: list[str], qaicc, weights, values: dict, *, delta: float = 4.0,
                  n_draws: int = 0, rng: np.random.Generator | None = None, differ: np.ndarray | None = None) -> dict:
    # many parameters: the candidate, the admissible hypotheses' QAICc, weights and values, and the draw options
    """The expected effect of measurement ``cand`` on the admissible hypotheses ``names``.

    ``qaicc``: their QAICc today; ``weights``: their Akaike weights (renormalised here); ``values``:
    parameter -> values over ``names`` (positive).  For each hypothesis taken as the truth, the
    chi-square the measurement adds to each (:meth:`ScalarCandidate.chi2`), the hypotheses within
    ``delta`` of the new best, and each parameter's ``max / min`` over them; averaged over ``n_draws``
    noise draws (0: the noise-free measurement) and over the truths by weight.

    Returns ``n_left`` (expected admissible hypotheses after), ``truth_kept`` (probability that the
    truth stays admissible), ``ratio_after`` and ``ratio_before`` (parameter -> max / min) and
    ``min_delta_chi2`` (the smallest noise-free chi-square between a truth and another hypothesis:
    how well the measurement separates the closest two; only the pairs ``differ[g, h]`` when given, e.g.
    those whose target parameter differs).
    """
    H = len(names)
    differ = ~np.eye(H, dtype=bool) if differ is None else np.asarray(differ, bool) & ~np.eye(H, dtype=bool)
    q = np.asarray(qaicc, float)
    w = np.asarray(weights, float)
    w = w / w.sum() if w.sum() > 0 else np.full(len(w), 1.0 / len(w))
    rng = rng or np.random.default_rng(0)
    n_left = kept = 0.0
    after = {p: 0.0 for p in values}
    sep = np.inf
    for g, name in enumerate(names):
        e0 = np.zeros(cand.noise_shape(1))
        c0 = cand.chi2(name, names, e0)[0]
        if differ[g].any():
            sep = min(sep, float(np.min(c0[differ[g]])))
        e = rng.standard_normal(cand.noise_shape(n_draws)) if n_draws else e0
        c = cand.chi2(name, names, e)
        qq = q[None, :] + c
        keep = admissible(qq, delta)
        n_left += w[g] * keep.sum(axis=1).mean()
        kept += w[g] * keep[:, g].mean()
        for p, r in _ranges(keep, values).items():
            after[p] += w[g] * r.mean()
    before = {p: float(np.max(v) / np.min(v)) for p, v in values.items()}
    return {"n_left": float(n_left), "truth_kept": float(kept), "ratio_after": {p: float(v) for p, v in after.items()},
            "ratio_before": before, "min_delta_chi2": float(sep) if np.isfinite(sep) else 0.0}


COLUMNS = ["rank", "measurement", "kind", "state", "sigma_pct", "min_delta_chi2", "expected_hypotheses_left",
           "truth_kept_fraction", "predictions", "target", "admissible_hypotheses"]


def _joint_values(records: dict, names: list[str]) -> dict:
    """Joint parameters (labels without an effect's dot) with a positive value in every hypothesis."""
    per = [{p["parameter"]: float(p["value"]) for p in records[n]["parameters"] if "." not in p["parameter"]}
           for n in names]
    keys = [k for k in per[0] if all(k in d and d[k] > 0 for d in per)]
    return {k: np.array([d[k] for d in per]) for k in keys}


def _scalar_candidates(records: dict, names: list[str], opts: ProposalOptions, sigma_m: float) -> list:
    preds = [records[n]["predictions"] for n in names]
    out = []
    m = [p.get("moving_mass_kg") for p in preds]
    if all(v is not None and np.isfinite(v) and v > 0 for v in m):
        out.append(ScalarCandidate("the weight of the moving part (table, carriages, motor primaries)", "weight",
                                   "", "kg", opts.weight_uncertainty_pct / 100, dict(zip(names, m))))
    rel = math.hypot(opts.static_stiffness_uncertainty_pct / 100, 2 * sigma_m)
    for si, st in enumerate(preds[0]["states"]):
        for label in st.get("static_stiffness_N_per_m", {}):
            v = [p["states"][si]["static_stiffness_N_per_m"].get(label) if si < len(p["states"]) else None
                 for p in preds]
            if all(x is not None and np.isfinite(x) and x > 0 for x in v):
                out.append(ScalarCandidate(f"{st['state']}: the static stiffness at {label}", "static stiffness",
                                           st["state"], "N/m", rel, dict(zip(names, v))))
    return out


def _shape_candidates(records: dict, names: list[str], q, w, values: dict, target: str,
                      opts: ProposalOptions, sigma_shape: float) -> list:
    """Per state measured without shapes (in every hypothesis's data), the DOF pair of least expected
    ``target`` range at the noise-free measurement (ties: fewer hypotheses left, then the larger smallest
    chi-square between hypotheses whose ``target`` differs)."""
    preds = [records[n]["predictions"] for n in names]
    labels = preds[0]["probe_labels"]
    eps = math.hypot(opts.shape_uncertainty_pct / 100, sigma_shape)
    w = np.asarray(w, float) / np.sum(w)
    out = []
    for si, st in enumerate(preds[0]["states"]):
        if any(p["states"][si].get("shapes_measured") for p in preds):
            continue
        cols = [p["states"][si]["paired_shapes"] for p in preds]
        modes = [k for k in range(len(cols[0])) if all(k < len(c) and c[k] is not None for c in cols)]
        if not modes:
            continue
        S = [np.array([c[k] for k in modes], float).T for c in cols]  # (n_labels, n_modes) each
        H, L = len(names), len(labels)
        chi = np.zeros((H, H, L, L))
        for g, h in itertools.product(range(H), range(H)):
            if g != h:
                chi[g, h] = pair_chi2(S[g], S[h], eps)
        qq = np.asarray(q, float)[None, :, None, None] + chi
        keep = admissible(qq, opts.delta, axis=1)  # (G, H, L, L)
        v = values[target][None, :, None, None]
        ratio = np.where(keep, v, -np.inf).max(axis=1) / np.where(keep, v, np.inf).min(axis=1)  # (G, L, L)
        exp_ratio = np.tensordot(w, ratio, axes=1)
        exp_left = np.tensordot(w, keep.sum(axis=1), axes=1)
        pairs = _differ(values[target])
        sep = np.min(chi[pairs], axis=0) if pairs.any() else np.zeros((L, L))
        iu = np.triu_indices(L, 1)
        order = np.lexsort((-sep[iu], _rounded(exp_left[iu]), _rounded(exp_ratio[iu])))
        i, j = iu[0][order[0]], iu[1][order[0]]
        ref = max((i, j), key=lambda k: float(np.min(np.abs(S[0][k]))))  # the one every mode moves most
        lead = j if ref == i else i
        vals = {n: np.vstack([S[h][lead], S[h][ref]]) for h, n in enumerate(names)}
        out.append(ShapePairCandidate(f"{st['state']}: the shapes of the {len(modes)} measured modes at "
                                      f"{labels[lead]} and {labels[ref]}", "shape", st["state"], "-", eps, vals))
    return out


SAME_REL = 0.01
"""Two hypotheses whose target parameter differs by less than this (relative) need not be told apart."""


def _differ(v: np.ndarray) -> np.ndarray:
    """``(H, H)``: the pairs of hypotheses whose values ``v`` differ by more than :data:`SAME_REL`."""
    lv = np.log(np.asarray(v, float))
    return np.abs(lv[:, None] - lv[None, :]) > math.log1p(SAME_REL)


def _rounded(x) -> np.ndarray:
    """Four significant digits (a sort key: float noise does not decide a tie)."""
    x = np.asarray(x, float)
    return np.array([float(f"{v:.4g}") for v in x.ravel()]).reshape(x.shape)


def propose(records: dict, rows: list[dict], opts: ProposalOptions | None = None, *,
            sigma_model_rel: float = 0.0, sigma_shape_rel: float = 0.0) -> tuple[pd.DataFrame, dict]:
    """The candidate measurements over the admissible hypotheses of a ranking (``rows`` of
    :func:`~jointid.reconstruction.ranking.rank_hypotheses`), best first.

    ``sigma_model_rel``: the frequency block's model error (relative), counted twice in a static
    stiffness; ``sigma_shape_rel``: the shape block's, beside the shape noise.  Returns the table
    (:data:`COLUMNS` plus ``<parameter>_ratio_before`` and ``_ratio_after`` per joint parameter) and a
    summary: ``admissible`` (names), ``target``, ``before``, ``best`` (the first row as a dict, or None)
    ``notes`` (what was not proposed, and why), ``reason`` (why nothing is proposed, or "") and ``caveats``
    (sentences on how far to trust a candidate).
    """
    opts = opts or ProposalOptions()
    adm = admissible_rows(rows, opts.delta)
    names = [r["hypothesis"] for r in adm]
    notes = ["a damping ratio — the hypotheses share one nominal modal damping ratio, so none predicts a damping "
             "of its own"]
    summary = {"admissible": names, "target": "", "before": float("nan"), "best": None, "notes": notes, "reason": "",
               "caveats": []}
    if len(names) < 2:
        summary["reason"] = f"{len(names)} admissible hypothesis, nothing to separate"
        return pd.DataFrame(columns=COLUMNS), summary
    if not all("predictions" in records[n] for n in names):
        summary["reason"] = "the hypotheses' records carry no predictions (written by an older version): rerun them"
        return pd.DataFrame(columns=COLUMNS), summary
    q = np.array([r["qaicc"] for r in adm], float)
    w = np.array([r["weight"] for r in adm], float)
    values = _joint_values(records, names)
    if not values:
        summary["reason"] = "no joint parameter is positive in every admissible hypothesis"
        return pd.DataFrame(columns=COLUMNS), summary
    spans = {p: float(v.max() / v.min()) for p, v in values.items()}
    target = opts.target if opts.target in values else max(spans, key=lambda p: (spans[p], p))
    summary.update(target=target, before=spans[target])
    cands = _scalar_candidates(records, names, opts, sigma_model_rel)
    cands += _shape_candidates(records, names, q, w, values, target, opts, sigma_shape_rel)
    if any(c.kind == "shape" for c in cands):
        summary["caveats"].append(
            "A DOF pair's predictions give, mode by mode, the displacement at its two DOFs in units of the "
            "mode's RMS over all measuring DOFs (a value near 0: that DOF sits near a node of the mode).")
    if any(c.kind == "shape" for c in cands) and sigma_shape_rel == 0.0:
        summary["caveats"].append(f"A DOF pair is judged at the stated shape noise alone: no shape is measured, so "
                                  f"the shapes' model error is unknown (the frequencies' is {100 * sigma_model_rel:.1f} "
                                  "% per mode). A larger shape noise (next_measurement.shape_uncertainty_pct) judges "
                                  "it more cautiously.")
    if any(any(p["states"][si].get("shapes_measured") for p in (records[n]["predictions"] for n in names))
           for si in range(len(records[names[0]]["predictions"]["states"]))):
        notes.append("a DOF pair in a state measured with shapes — its shapes are in the fits already")
    out = []
    for c in cands:
        g = expected_gain(c, names, q, w, values, delta=opts.delta, n_draws=opts.n_draws,
                          rng=np.random.default_rng(opts.seed), differ=_differ(values[target]))
        row = {"measurement": c.measurement, "kind": c.kind, "state": c.state, "sigma_pct": 100 * c.rel,
               "min_delta_chi2": g["min_delta_chi2"], "expected_hypotheses_left": g["n_left"],
               "truth_kept_fraction": g["truth_kept"], "predictions": c.predictions_text(names),
               "target": target, "admissible_hypotheses": len(names)}
        for p in values:
            row[f"{p}_ratio_before"] = g["ratio_before"][p]
            row[f"{p}_ratio_after"] = g["ratio_after"][p]
        out.append(row)
    df = pd.DataFrame(out)
    if len(df):
        key = df.assign(_r=_rounded(df[f"{target}_ratio_after"]), _n=_rounded(df["expected_hypotheses_left"]))
        df = df.loc[key.sort_values(["_r", "_n", "min_delta_chi2"], ascending=[True, True, False],
                                    kind="stable").index].reset_index(drop=True)
        df.insert(0, "rank", np.arange(1, len(df) + 1))
        summary["best"] = df.iloc[0].to_dict()
    return df, summary


def next_measurement_markdown(df: pd.DataFrame, summary: dict, opts: ProposalOptions | None = None) -> list[str]:
    """The section "The measurement that would narrow the reconstruction" of ranking.md (lines)."""
    opts = opts or ProposalOptions()
    lines = ["", "## The measurement that would narrow the reconstruction", ""]
    names, target, best = summary["admissible"], summary["target"], summary["best"]
    if best is None:
        lines += [f"No measurement proposed: {summary['reason'] or 'no candidate is predicted by every hypothesis'}."]
        return lines
    lines += [f"Over the {len(names)} admissible hypotheses ({', '.join(names)}), {target} spans "
              f"×{summary['before']:.2f}. **Next measurement: {best['measurement']}** (1σ {best['sigma_pct']:.1f} %): "
              f"on synthetic data drawn from the admissible hypotheses it would narrow {target} to "
              f"×{best[f'{target}_ratio_after']:.2f} and leave {best['expected_hypotheses_left']:.1f} hypotheses "
              f"admissible (the truth kept in {100 * best['truth_kept_fraction']:.0f} % of draws).", "",
              f"Each admissible hypothesis taken as the truth ({opts.n_draws} seeded noise draws each, truths "
              "weighted by their Akaike weights): the measurement's chi-square added to every hypothesis's QAICc, "
              f"the admissible ones kept (within ΔQAICc < {opts.delta:g} of the new best, or in the 95 % confidence set; next_measurements.csv; "
              f"docs/reconstruction.md). Smallest Δχ²: the noise-free chi-square between the closest two hypotheses "
              f"whose {target} differs by more than {100 * SAME_REL:g} %.", "",
              f"| rank | measurement | 1σ (%) | smallest Δχ² | hypotheses left | {target} range after |",
              "|---:|---|---:|---:|---:|---:|"]
    for _, r in df.iterrows():
        lines.append(f"| {r['rank']} | {r['measurement']} | {r['sigma_pct']:.1f} | {r['min_delta_chi2']:.2g} | "
                     f"{r['expected_hypotheses_left']:.1f} | ×{r[f'{target}_ratio_after']:.2f} |")
    lines += [""] + list(summary.get("caveats", [])) + [f"Not proposed: {n}." for n in summary["notes"]]
    return lines
