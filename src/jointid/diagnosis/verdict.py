"""The verdict of the diagnosis in words (docs/effects.md, "Reading the verdict").

:func:`verdict_text` turns the findings into one paragraph and its short form (``explained_by``):

* ``none needed`` — the current model fits within the noise (with the effects the fitted joints
  could be hiding, if any);
* ``<effect>`` — one library effect brings the model to the noise level;
* ``<a> or <b>`` — several do, within ``tie_delta_aicc``: the data cannot tell them apart; how far
  their refits differ and which measurement would decide are said;
* ``<a>+<b>`` — no single effect does, a combination does;
* ``unexplained`` — no listed effect nor combination up to ``max_effects`` does.

No number is printed as NaN: a state with no paired mode says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from jointid.diagnosis.judging import SUPPORTED, parsimonious_order, unconfirmed_pairs
from jointid.diagnosis.results import Fit
from jointid.identification.model_error import NO_MODEL_ERROR, ModelError

__all__ = ["Findings", "verdict_text", "state_errors_text", "daicc"]


@dataclass
class Findings:
    """What the verdict is made of."""

    current: Fit
    ranking: pd.DataFrame
    alpha: float
    between_share: float = 0.0
    combinations: pd.DataFrame = field(default_factory=pd.DataFrame)
    absorbed: list = field(default_factory=list)  # sentences
    tie_detail: str = ""
    next_measurements: pd.DataFrame = field(default_factory=pd.DataFrame)
    identifiable: dict = field(default_factory=dict)  # fit label (current, +A, +A+B) -> sentence
    max_effects: int = 2
    model_error: ModelError = NO_MODEL_ERROR
    current_weight: float = 1.0


def daicc(value: float) -> str:
    """A delta AICc for the text: ``-12.3``, or why there is none."""
    v = float(value)
    return f"{v:.1f}" if np.isfinite(v) else "undefined: too few residuals for the parameters"


def state_errors_text(summary: list[dict]) -> str:
    """Per state ``max .. % rms .. %`` (``no paired mode`` where there is none)."""
    out = []
    for s in summary:
        if not np.isfinite(s["max_abs_error_pct"]):
            out.append(f"{s['state']}: no paired mode")
        else:
            out.append(f"{s['state']} max {s['max_abs_error_pct']:.2f} % rms {s['rms_error_pct']:.2f} %")
    return ", ".join(out)


def _max_error(summary: list[dict]) -> float:
    vals = [s["max_abs_error_pct"] for s in summary if np.isfinite(s["max_abs_error_pct"])]
    return max(vals) if vals else float("nan")


def chi2_text(fit: Fit) -> str:
    """``chi2 = .. for .. degrees of freedom, p = ..`` per block (frequencies; shapes where fitted)."""
    blocks = fit.block_chi2()
    if len(blocks) == 1:
        return f"chi2 = {fit.chi2:.1f} for {fit.dof} degrees of freedom, p = {fit.p_value:.2g}"
    from jointid.diagnosis.criteria import chi2_p_value

    return "; ".join(f"{ {'frequency': 'frequencies'}.get(name, name + 's')} chi2 = {c:.1f} for {d} degrees of freedom, p = {chi2_p_value(c, d):.2g}"
                     for name, c, d in blocks)


def verdict_text(f: Findings, data) -> tuple[str, str]:
    """The verdict in words and its short form (see the module doc).  Its first sentence is the
    answer: the missing effect with its value and interval, or that the model fits within the noise,
    or the supported effect that leaves a model error, or that nothing is supported and by what
    factor the misfit exceeds the stated noise."""
    summ = f.current.state_summary(data)
    cur_txt = state_errors_text(summ)
    if f.current.p_value >= f.alpha:
        verdict = (f"The current model ({f.current.variant.name}) explains the data within the noise "
                   f"({chi2_text(f.current)}; {cur_txt}); no effect is needed to explain them.")
        if f.absorbed:
            verdict += " But " + "; and ".join(f.absorbed) + "."
        return verdict + _identifiable(f, ["current"]), "none needed"
    explaining = f.ranking[f.ranking["explains"].astype(bool)]
    if len(explaining):
        best = explaining.iloc[0]
        tied = [str(best["effect"])] + [n for n in str(best.get("indistinguishable_from") or "").split(";") if n]
        if len(tied) > 1:
            verdict, short = _tie_text(f, explaining, tied, _max_error(summ)), " or ".join(tied)
            verdict += _identifiable(f, ["+" + n for n in tied])
        else:  # the single effect's row carries what the data identify of it
            verdict, short = missing_effect_text(best, _max_error(summ)), str(best["effect"])
        return verdict + between_states_text(f.ranking, f.between_share), short
    combos = f.combinations
    if len(combos) and combos["explains"].any():
        best = combos[combos["explains"]].iloc[0]
        verdict = combination_text(best, combos, _max_error(summ), f.ranking)
        return verdict + _identifiable(f, ["+" + str(best["effects"])]), str(best["effects"])
    verdict = lead_sentence(f) + " " + unexplained_text(f.current, f.ranking, cur_txt, combos, f.max_effects)
    verdict += partial_text(f)
    return (verdict + between_states_text(f.ranking, f.between_share)
            + _identifiable(f, ["current"]), "unexplained")


def _identifiable(f: Findings, labels: list) -> str:
    """What the data identify of em_preload in the first of the fits ``labels`` that has it."""
    key = next((lab for lab in labels if lab in f.identifiable), None)
    if key is None:
        return ""
    where = "the current model" if key == "current" else f"the refit with {key[1:].replace('+', ' + ')}"
    return f" Of em_preload in {where}, the data identify the {f.identifiable[key]}"


def missing_effect_text(best: pd.Series, max_error_pct: float) -> str:
    """The verdict naming the missing effect ``best`` (a ranking row) and what enabling it achieves;
    what the data identify of it (its ``identifiable`` column) comes before its raw parameter."""
    unit = "" if best["unit"] in ("-", "") else f" {best['unit']}"
    raw = (f"{best['parameter']} = {best['estimate']:.4g}{unit} (95 % CI {best['ci95_low']:.3g} .. "
           f"{best['ci95_high']:.3g})")
    ident = best.get("identifiable")
    what = f"the data identify the {ident} Its parameter as fitted: {raw}" if isinstance(ident, str) and ident else raw
    return (f"Missing effect: {best['effect']} ({best['title']}): {what}. "
            f"It explains {100 * best['explained_fraction']:.0f} % of the residual to first order; refitted, "
            f"the error falls from max {max_error_pct:.2f} % to "
            f"{best['max_abs_error_pct_after']:.2f} % and chi2 is consistent with the noise "
            f"(p = {best['fit_p_value']:.2g}, ΔQAICc = {daicc(best['delta_qaicc'])}). Enable it with "
            f"effects: {{{_enable(best)}}} in config.yaml.")


def _enable(row: pd.Series) -> str:
    """The ``effects:`` entry that enables a candidate (with a profiled option, if any)."""
    e = row.get("enable_with")
    return str(e) if isinstance(e, str) and e else f"{row['effect']}: {{}}"


def _tie_text(f: Findings, explaining: pd.DataFrame, tied: list[str], max_error_pct: float) -> str:
    rows = explaining.set_index("effect").loc[tied]
    each = "; ".join(f"{n}: {r['parameter']} = {r['estimate']:.4g} {r['unit']} (ΔQAICc {daicc(r['delta_qaicc'])}, "
                     f"p = {r['fit_p_value']:.2g}, max error {r['max_abs_error_pct_after']:.2f} %)"
                     for n, r in rows.iterrows())
    txt = (f"Missing effect: {' or '.join(tied)} (the data cannot tell them apart). Each refitted brings the "
           f"error from max {max_error_pct:.2f} % to the noise level, within ΔQAICc < "
           f"{f.ranking.attrs.get('tie_delta_aicc', 4.0):g} of each other: {each}.")
    if f.tie_detail:
        txt += f" {f.tie_detail}"
    nm = f.next_measurements
    if len(nm):
        items = "; ".join(f"({i + 1}) {r.measurement}, expected chi-square difference {r.expected_delta_chi2:.1f} "
                          f"[{r.predictions}]" for i, r in enumerate(nm.itertuples()))
        txt += f" The measurements that would best decide: {items}."
    else:
        txt += " No further mode or force level of this test separates them by more than the noise."
    return txt


def combination_text(best: pd.Series, combos: pd.DataFrame, max_error_pct: float, ranking: pd.DataFrame) -> str:
    """The verdict naming a combination of effects that explains the data (no single one does)."""
    names = str(best["effects"]).split("+")
    others = combos[combos["explains"] & (combos["effects"] != best["effects"])
                    & ((combos["delta_qaicc"] - best["delta_qaicc"]).abs()
                       < ranking.attrs.get("tie_delta_aicc", 4.0))]
    lead = ranking[ranking["delta_qaicc"].notna()]
    first = lead.iloc[0] if len(lead) else None
    single = (f"the best single one, {first['effect']}, leaves max {first['max_abs_error_pct_after']:.2f} % "
              f"(p = {first['fit_p_value']:.2g})" if first is not None else "")
    txt = (f"Missing effects: {' and '.join(names)} together ({best['estimates']}). No single library effect "
           f"explains the residual ({single}); together the error falls from max {max_error_pct:.2f} % to "
           f"{best['max_abs_error_pct_after']:.2f} % and chi2 is consistent with the noise "
           f"(p = {best['fit_p_value']:.2g}, ΔQAICc = {daicc(best['delta_qaicc'])}). Enable them with effects: "
           f"{{{', '.join(n + ': {}' for n in names)}}} in config.yaml.")
    if len(others):
        txt += (" Within the same QAICc, " + " or ".join(str(e) for e in others["effects"])
                + " explain the data as well: the data cannot tell these combinations apart.")
    return txt


def unexplained_text(current: Fit, ranking: pd.DataFrame, cur_txt: str, combos: pd.DataFrame,
                     max_effects: int) -> str:
    """The verdict when no listed effect (nor combination) explains the residual."""
    lead = ranking.iloc[0] if len(ranking) else None
    part = ""
    if lead is not None and lead.get("score", 0) > 0:
        part = (f" The closest candidate, {lead['effect']}, explains {100 * lead['explained_fraction']:.0f} % "
                f"of the residual to first order")
        if np.isfinite(float(lead.get("fit_p_value", np.nan))):
            part += (f" but leaves max {lead['max_abs_error_pct_after']:.2f} % error "
                     f"(refit p = {lead['fit_p_value']:.2g})")
        part += "."
    if len(combos):
        c = combos.iloc[0]
        part += (f" No pair of the leading candidates does either: the best, {c['effects']}, leaves max "
                 f"{c['max_abs_error_pct_after']:.2f} % (p = {c['fit_p_value']:.2g}).")
    tried = "single effects" if max_effects <= 1 or not len(combos) else f"up to {min(max_effects, 2)} effects at once"
    enabled, why = [s.effect.name for s in current.variant.effects], ""
    if enabled:
        tried += f" on top of {', '.join(enabled)}"
        if not len(combos) and 1 < max_effects < len(enabled) + 2:
            why = f"; pairs on top would exceed diagnosis.max_effects = {max_effects} effects in one model"
    return (f"No listed effect explains the residual to the noise "
            f"({tried} tried{why}; "
            f"{cur_txt}; {chi2_text(current)})." + part)


def lead_sentence(f: Findings) -> str:
    """The answer when nothing brings the model to the noise: the best supported candidate with its value,
    interval and the model error it leaves; or that nothing is supported, and the misfit against the
    stated noise."""
    me = f.model_error
    judged = _judged(f)
    sup = _supported(f, judged)
    known = (f"; beside the mesh's known error of {100 * me.sigma_known_rel:.2g} %, a model error of about "
             f"{100 * me.sigma_model_rel:.2g} % per mode remains" if me.sigma_known_rel > 0 else "")
    if not len(sup):
        return (f"Nothing is supported: no listed effect or pair removes a part of the misfit that the data "
                f"support, and the misfit is {np.sqrt(max(me.c_hat, 0.0)):.1f} times the stated noise of "
                f"{100 * me.sigma_noise_rel:.2g} % per mode (chi2/dof = {me.c_hat:.1f}{known}).")
    b = sup.iloc[0]
    name = str(b["name"])
    value = ""
    if " + " not in name and name in set(f.ranking["effect"]):
        r = f.ranking.set_index("effect").loc[name]
        unit = "" if r["unit"] in ("-", "") else f" {r['unit']}"
        value = (f", {r['parameter']} = {r['estimate']:.3g}{unit} (95 % interval {r['ci95_low']:.3g} .. "
                 f"{r['ci95_high']:.3g})")
    elif " + " in name and len(f.combinations):
        c = f.combinations[f.combinations["effects"].astype(str) == name.replace(" + ", "+")]
        value = f" ({c.iloc[0]['estimates']})" if len(c) else ""
    left = []
    if me.sigma_model_rel > 0:
        left.append(f"a model error of about {100 * me.sigma_model_rel:.2g} % per mode remains")
    if me.shape is not None and me.shape.above_noise:
        left.append(f"the mode shapes keep a model error of about {100 * me.shape.sigma_model_rel:.2g} % of each "
                    "mode's RMS")
    rest = " and ".join(left) if left else "the best fit tried leaves no model error beyond the noise"
    return (f"Supported effect: {name}{value}, {b['support']} supported (ΔQAICc {daicc(b['delta_qaicc'])}), "
            f"removing {100 * b['removed_fraction']:.0f} % of the misfit; {rest}.")


def _supported(f: Findings, judged: pd.DataFrame) -> pd.DataFrame:
    """The supported rows of ``judged``, the answer first (a pair yields to its own single within the tie
    window: :func:`jointid.diagnosis.judging.parsimonious_order`)."""
    sup = judged[judged["support"].isin(SUPPORTED)]
    tie = float(f.ranking.attrs.get("tie_delta_aicc", 4.0))
    order = parsimonious_order(zip(sup["delta_qaicc"], sup["name"]), tie, unconfirmed_pairs(f.combinations))
    return sup.set_index("name", drop=False).loc[order].reset_index(drop=True)


def _judged(f: Findings) -> pd.DataFrame:
    """The refitted singles and the pairs, with their judged columns, best QAICc first."""
    cols = ["name", "delta_qaicc", "weight", "support", "removed_fraction", "max_abs_error_pct_after"]
    r = f.ranking[f.ranking["delta_qaicc"].notna()].rename(columns={"effect": "name"}) \
        if "delta_qaicc" in f.ranking else pd.DataFrame(columns=cols)
    c = f.combinations.rename(columns={"effects": "name"}) if len(f.combinations) else pd.DataFrame(columns=cols)
    c = c.assign(name=c["name"].astype(str).str.replace("+", " + ", regex=False))
    both = pd.concat([r.reindex(columns=cols), c.reindex(columns=cols)], ignore_index=True)
    return both.sort_values("delta_qaicc", kind="stable").reset_index(drop=True)


def partial_text(f: Findings) -> str:
    """When nothing reaches the noise: what the best supported candidate (single or pair) removes and
    how strongly the data support it, the candidates tied with it, and the model error that remains;
    or, with none supported, the misfit against the stated noise (docs/effects.md, "Reading the verdict")."""
    me = f.model_error
    judged = _judged(f)
    sup = _supported(f, judged)
    if not len(sup):
        ratio = np.sqrt(max(me.c_hat, 0.0))
        best = f" (the best, {judged.iloc[0]['name']}, ΔQAICc {daicc(judged.iloc[0]['delta_qaicc'])})" \
            if len(judged) else ""
        return (f" No listed effect or pair removes a part of the misfit that the data support against the "
                f"model error{best}. The misfit is about {ratio:.1f} times the stated noise of "
                f"{100 * me.sigma_noise_rel:.2g} % (chi2/dof = {me.c_hat:.1f} for {me.reference}): either the "
                f"noise is understated by that factor, or the model has an error of about "
                f"{100 * me.sigma_model_rel:.2g} % per mode that no listed effect explains.")
    b = sup.iloc[0]
    tie = f.ranking.attrs.get("tie_delta_aicc", 4.0)
    # within the tie of the best, leaving out the best with one more effect (it adds nothing supported)
    others = [str(n) for n, d in zip(sup["name"].iloc[1:], sup["delta_qaicc"].iloc[1:])
              if d - b["delta_qaicc"] < tie and not set(str(b["name"]).split(" + ")) < set(str(n).split(" + "))]
    txt = (f" {b['name']} removes {100 * b['removed_fraction']:.0f} % of the misfit and is {b['support']} "
           f"supported (ΔQAICc {daicc(b['delta_qaicc'])} against the current model, weight {b['weight']:.2f}); "
           f"refitted, the max error is {b['max_abs_error_pct_after']:.2f} %.")
    if others:
        txt += (f" Within ΔQAICc < {tie:g} of it, {' or '.join(others)} do as well: the data cannot tell them "
                "apart.")
    txt += unconfirmed_text(f, sup, str(b["name"]))
    return txt + (f" A model error of about {100 * me.sigma_model_rel:.2g} % per mode remains "
                  f"({me.sigma_model_rel / me.sigma_noise_rel:.1f} times the stated noise of "
                  f"{100 * me.sigma_noise_rel:.2g} %) that no listed effect or pair explains.")


def unconfirmed_text(f: Findings, sup: pd.DataFrame, lead: str) -> str:
    """The sentence on the pairs that extend ``lead``, fit better, and do not predict the modes left out
    better (:mod:`jointid.diagnosis.predictive`): why the lead is the simpler model ("" when none)."""
    weak = set(unconfirmed_pairs(f.combinations))
    d_lead = float(sup.set_index("name").loc[lead, "delta_qaicc"]) if lead in set(sup["name"]) else np.inf
    out = []
    for _, c in f.combinations.iterrows() if len(f.combinations) else []:
        names = str(c["effects"]).split("+")
        if str(c["effects"]) not in weak or lead not in names or not c["delta_qaicc"] < d_lead:
            continue
        extra = next(n for n in names if n != lead)
        delta, mode = c["prediction_delta"], int(c.get("prediction_worst_mode", 0) or 0)
        if not np.isfinite(delta):
            how = f"with mode {mode} left out, {extra}'s parameter is free: it rests on that mode alone"
        else:
            how = (f"leave-one-mode-out, -2 log of the predictive density rises by {delta:.3g} ± "
                   f"{c['prediction_se']:.2g}")
            if mode > 0:
                how += (f"; mode {mode} left out is predicted at {c['prediction_worst_pair']:.3g} against "
                        f"{c['prediction_worst_single']:.3g} by {c['prediction_vs']} alone")
        out.append(f" {lead} + {extra} fits better (ΔQAICc {daicc(c['delta_qaicc'])}) but predicts the modes "
                   f"left out no better than {c['prediction_vs']} alone ({how}): {extra} is not confirmed by "
                   "the data.")
    return "".join(out)


def between_states_text(ranking: pd.DataFrame, between_share: float) -> str:
    """The sentence on the between-state part of the residual ("" when it is 5 % or less)."""
    if not (between_share > 0.05 and ranking["between_states_fraction"].notna().any()):
        return ""
    b = ranking.sort_values("between_states_fraction", ascending=False, kind="stable").iloc[0]
    if b["between_states_fraction"] > 0.5:
        return (f" Of the residual, {100 * between_share:.0f} % differs between the states; "
                f"{b['effect']} explains {100 * b['between_states_fraction']:.0f} % of that "
                f"between-state part (p = {b['between_states_p_value']:.2g}).")
    return (f" Of the residual, {100 * between_share:.0f} % differs between the states; no listed "
            "effect explains that between-state part.")
