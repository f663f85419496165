"""The diagnosis's fits judged with the model error (:mod:`jointid.identification.model_error`).

Two questions are kept apart (docs/effects.md, "Reading the verdict"):

* how much of the misfit a candidate removes (``removed_fraction``, the share of the current model's
  chi-square it takes away) and how strongly the data support it (``delta_qaicc`` against the current
  model, ``weight`` among all the models compared, ``support``);
* whether what remains is at the noise (``explains``: the chi-square p-value at the stated noise).

The model error ``sigma_m`` comes from the fit of least chi-square per degree of freedom among all the
fits of the diagnosis (the current model, the single refits and the pairs: the most general models
tried) and is held fixed while they are compared.  Where that fit is within its noise, QAICc is AICc.
"""

from __future__ import annotations

import numpy as np

from dataclasses import replace

from jointid.diagnosis.results import Fit, block_error, chi2_at
from jointid.identification.model_error import ModelError, akaike_weights, qaicc, support_text

__all__ = ["SUPPORTED", "effect_set", "fit_label", "judge_fits", "model_error_of", "parsimonious_order", "qaicc_of",
           "supported", "unconfirmed_pairs"]

SUPPORTED = ("strongly", "moderately")
"""The ``support`` values of a candidate the data support against the current model."""


def fit_label(label: str) -> str:
    """A fit's label in words: ``baseline`` -> ``the baseline``, ``+a+b`` -> ``the refit with a + b``."""
    if not label.startswith("+"):
        return f"the {label}"
    return "the refit with " + " + ".join(label[1:].split("+"))


def lack_of_fit(f: Fit) -> float:
    """The sum over the blocks of chi-square per degree of freedom (one block: ``chi2 / dof``)."""
    return sum(c / d for _, c, d in f.block_chi2())


def model_error_of(fits: dict, data) -> ModelError:
    """The model error of the diagnosis, from its fit of least lack of fit (:func:`lack_of_fit`: chi-square
    per degree of freedom, summed over the frequency and shape blocks); each block's own error."""
    label = min(fits, key=lambda k: (lack_of_fit(fits[k]), k))
    f = fits[label]
    me = block_error(f.ev, data, f.k, reference=fit_label(label))
    if me.shape is not None:  # shape rows that move together within a mode count as fewer rows
        me = replace(me, shape=replace(me.shape, design_effect=f.shape_design_effect()))
    return me


def qaicc_of(f: Fit, data, me: ModelError, n_params: int | None = None) -> float:
    """QAICc of fit ``f`` at the total uncertainty of ``me`` (``n_params`` counts parameters profiled
    outside ``f.x`` too; default ``f.k``)."""
    return qaicc(chi2_at(f.ev, data, me), f.n, f.k if n_params is None else n_params)


def judge_fits(current: Fit, fits: dict, rows: list[dict], combos: list[dict], data, me: ModelError) -> float:
    """Fill the judged columns of the refitted candidates' ``rows`` (ranking rows naming ``effect``) and
    of the ``combos`` rows (naming ``effects`` ``a+b``): ``delta_qaicc`` against the current model,
    ``removed_fraction``, ``weight`` (Akaike weight at the total uncertainty among the current model,
    the single refits and the pairs) and ``support``.  Returns the current model's weight."""
    q_cur = qaicc_of(current, data, me)
    judged = []
    for row in rows:
        f = fits.get("+" + str(row.get("effect")))
        if f is not None and "fit_n_params" in row:
            judged.append((row, f, int(row["fit_n_params"])))
    for row in combos:
        judged.append((row, fits["+" + str(row["effects"])], None))
    q = [qaicc_of(f, data, me, k) for _, f, k in judged]
    w = akaike_weights([q_cur] + q)
    for (row, f, _), qi, wi in zip(judged, q, w[1:]):
        d = qi - q_cur
        row.update({"delta_qaicc": d, "weight": float(wi), "support": support_text(d),
                    "removed_fraction": float(1 - f.chi2 / current.chi2) if current.chi2 > 0 else 0.0})
    return float(w[0])


def supported(rows) -> np.ndarray:
    """Which rows (a DataFrame) are supported against the current model (``support`` strongly or
    moderately; rows not refitted have none)."""
    return rows["support"].isin(SUPPORTED).to_numpy()


def effect_set(name: str) -> frozenset:
    """The effects of a candidate's name (``a``, ``a+b`` or ``a + b``)."""
    return frozenset(p.strip() for p in str(name).split("+") if p.strip())


def parsimonious_order(candidates, tie: float, no_gain=()) -> list[str]:
    """The candidate names ``[(delta_qaicc, name), ...]`` best first, except that a combination at the
    top yields the lead to the smallest of its own sub-models within ``tie`` of it (fewest effects, then
    least QAICc): the extra effect is then not supported against the simpler model, so the simpler model
    is the answer (Burnham & Anderson 2002, sec. 2.6: an added parameter that does not lower AIC by more
    than its penalty is not supported).  A combination named in ``no_gain`` (it does not predict the
    modes left out better than its singles: :mod:`jointid.diagnosis.predictive`) yields to its best
    sub-model whatever the QAICc difference."""
    ranked = sorted(candidates, key=lambda c: c[0])
    if not ranked:
        return []
    d0, best = ranked[0]
    weak = {effect_set(n) for n in no_gain}
    inner = [(len(effect_set(n)), d, n) for d, n in ranked[1:]
             if (d - d0 < tie or effect_set(best) in weak) and effect_set(n) < effect_set(best)]
    if not inner:
        return [n for _, n in ranked]
    lead = min(inner)[2]
    return [lead] + [n for _, n in ranked if n != lead]


def supported_order(ranking, combos) -> list[str]:
    """The refitted candidates (``ranking``, column ``effect``) and pairs (``combos``, column ``effects``)
    the data support against the current model, best first (a pair after its own single when they tie or
    it does not predict better: :func:`parsimonious_order`)."""
    out = []
    for df, col in ((ranking, "effect"), (combos, "effects")):
        if len(df) and "support" in df:
            ok = df[df["support"].isin(SUPPORTED)]
            out += list(zip(ok["delta_qaicc"], ok[col].astype(str)))
    return parsimonious_order(out, float(ranking.attrs.get("tie_delta_aicc", 4.0)), unconfirmed_pairs(combos))


def unconfirmed_pairs(combos) -> list[str]:
    """The pairs of a combinations table (``effects`` ``a+b``) that do not predict the left-out modes
    better than their singles (``predicts`` False; :func:`jointid.diagnosis.predictive.check_pairs`)."""
    if not len(combos) or "predicts" not in combos:
        return []
    return [str(e) for e, ok in zip(combos["effects"], combos["predicts"]) if not ok]  # NaN: not checked
