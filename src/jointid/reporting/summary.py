"""The summary card at the top of the report page: the numbers a reader looks for first.

* :func:`card_items` - one sentence each: the max errors of Tables 2/3, the joint stiffnesses with
  their 95 % intervals per state, Table 1's status, the model error and the diagnosis verdict;
* :func:`key_numbers` - Table 1 (status, identified value or why not, the lowest paired peak), its
  increases, the ranges, the frequency errors, the damping, Table 1's problems and the model error,
  as the template ``page.html.j2`` renders them;
* :func:`model_error_text` - the model error of each state's fit and of the best reconstruction
  hypothesis, in one sentence.

The page around it is :func:`jointid.reporting.page.build_html`.
"""

from __future__ import annotations

import pandas as pd

__all__ = ["card_items", "key_numbers", "model_error_text", "sci"]


def key_numbers(data: dict) -> dict:
    """The key numbers above the sections: Table 1 (status, identified value or why not, the lowest
    paired peak), its increases, the ranges, the frequency errors, the damping, Table 1's problems and
    the model error (:func:`model_error_text`)."""
    t1 = data["table1"]
    d0 = next(iter(data["stiffness"].values()))
    num = lambda v, f: "–" if pd.isna(v) else format(v, f)  # noqa: E731
    stiffness = []
    for _, r in t1.iterrows():
        value = (f"{r.dynamic_stiffness_N_per_mm:,.0f} N/mm" if r.status == "identified" else
                 f"not identified ({r.not_identified_dynamic_stiffness_N_per_mm:,.0f} N/mm at unpaired FE mode "
                 f"{r.governing_mode}, {r.governing_description})")
        if bool(getattr(r, "status_rests_on_tie", False)):
            value += " — rests on a tie: " + str(r.tie_note)
        stiffness.append({"state": r.state.replace("_", "-"), "value": value,
                          "paired": num(r.paired_dynamic_stiffness_N_per_mm, ",.0f"),
                          "paper": f"{r.paper_dynamic_stiffness_N_per_mm:,.0f}"})
    rng = data.get("table1_ranges")
    ranges = [] if rng is None else [
        {"basis": r.basis, "over": r.over, "value": f"{num(r.increase_low_pct, '+.1f')} … {num(r.increase_high_pct, '+.1f')}",
         "inside": "inside" if r.paper_inside in (True, "True") else "outside"}
        for r in rng.itertuples() if r.over == "points × damping laws"]
    return {
        "stiffness": stiffness,
        "increase": [{"value": "n/a (a state is not identified)" if pd.isna(r.increase_pct) else f"{r.increase_pct:+.1f} %",
                      "paired": num(r.paired_increase_pct, "+.1f"),
                      "paper": f"{r.paper_increase_pct:+.1f}"} for _, r in t1[t1.paper_increase_pct.notna()].iterrows()],
        "ranges": ranges,
        "errors": "; ".join(f"{s.replace('_', '-')} max |error| {t.relative_error_pct.abs().max():.1f} % "
                            f"(paper {t.paper_relative_error_pct.abs().max():.1f} %)"
                            for s, t in data["tables"].items()),
        "damping": ", ".join(f"{k} = {v}" for k, v in d0["damping"]["config"].items()),
        "damping_note": ("(the paper publishes no damping)" if d0["damping"].get("source", "assumed") == "assumed" else
                         f"({d0['damping']['source']} damping used instead: see Table 1's notes)"),
        "problems": data.get("table1_problems", []),
        "model_error": model_error_text(data),
    }


def model_error_text(data: dict) -> str:
    """The model error of each state's identification, and of the hypotheses' comparison when there is
    one: the fit's remaining error per mode beside the stated noise (docs/effects.md, "Statistics")."""
    parts = []
    for state, p in data["params"].items():
        me = p.model_error
        if me:
            parts.append(f"{state.replace('_', '-')}: about {me['sigma_model_pct']:.1f} % per mode "
                         f"(χ²/dof = {me['c_hat']:.0f} at the stated {me['sigma_noise_pct']:.2g} %)")
    h = data.get("hypotheses")
    if h is not None and "sigma_model_pct" in h["ranking"]:
        r = h["ranking"].iloc[0]
        parts.append(f"the best reconstruction hypothesis ({r.hypothesis}, both states): about "
                     f"{r.sigma_model_pct:.1f} % per mode (χ²/dof = {r.c_hat:.0f})")
    if not parts:
        return ""
    return ("Model error, the part of the misfit the stated noise does not cover: " + "; ".join(parts)
            + ". Intervals, rankings and weights are widened by it.")


_SUP = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def sci(v: float) -> str:
    """``v`` to three significant digits, as 7.96·10¹¹ (plain below 10⁴)."""
    if pd.isna(v):
        return "–"
    m, e = f"{v:.2e}".split("e")
    return f"{v:.3g}" if abs(v) < 1e4 else f"{m}·10{str(int(e)).translate(_SUP)}"


def _stiffness_sentences(data: dict) -> list[str]:
    out = []
    for state, p in data["params"].items():
        parts = [f"{name.replace('_N_per_m3', '')} {sci(v.value)} ({sci(v.ci95_low)} … {sci(v.ci95_high)})"
                 for name, v in p.parameters.items()]
        unit = " N/m³" if all(n.endswith("_N_per_m3") for n in p.parameters) else ""
        out.append(f"{state.replace('_', '-')}: " + ", ".join(parts) + unit + ".")
    return out


def _table1_sentence(data: dict) -> str:
    t1, d0 = data["table1"], next(iter(data["stiffness"].values()))
    ok = t1["status"] == "identified"
    status = (("Both states" if len(t1) == 2 else "Every state") + " identified" if ok.all() else
              ", ".join(f"{r.state.replace('_', '-')} {r.status.split(':')[0]}" for r in t1.itertuples()).capitalize())
    tie = t1["status_rests_on_tie"].astype(bool) if "status_rests_on_tie" in t1 else pd.Series(False, t1.index)
    if tie.any():
        status += (" (each on a tie between pairings, see Table 1)" if tie.all() else
                   f" ({', '.join(s.replace('_', '-') for s in t1.loc[tie, 'state'])} on a tie between pairings, "
                   "see Table 1)")
    vals = "; ".join(f"{r.state.replace('_', '-')} "
                     + (f"{r.dynamic_stiffness_N_per_mm:,.0f} N/mm" if r.status == "identified" else "not identified")
                     + f" (paper {r.paper_dynamic_stiffness_N_per_mm:,.0f} N/mm)" for r in t1.itertuples())
    inc = "; ".join(("increase n/a" if pd.isna(r.increase_pct) else f"increase {r.increase_pct:+.1f} %")
                    + f" (paper {r.paper_increase_pct:+.1f} %)" for r in t1[t1.paper_increase_pct.notna()].itertuples())
    checks = (f" The Table 1 check finds {len(data.get('table1_problems') or [])} problem(s), listed below."
              if data.get("table1_problems") else "")
    return f"{status}: K_dyn,min in {d0['direction'].upper()} at {d0['drive_point']} {vals}; {inc}.{checks}"


def _diagnosis_sentences(data: dict) -> list[str]:
    from jointid.reporting.diagnosis_summary import short_verdict

    diag = data.get("diagnosis") or {}
    if not diag:
        return ["The diagnosis is not part of this run."]
    texts = {n: short_verdict(d["verdict"]["explained_by"], d["ranking"], d.get("combinations")).rstrip(".")
             for n, d in diag.items()}
    return [f"{name}: {t[:1].lower() + t[1:]} (page: {diag[name]['page']})." for name, t in texts.items()]


def card_items(data: dict) -> list[dict]:
    """The summary card's items, ``{"label", "lines"}``, one sentence each (the joint stiffness one per
    state): Tables 2/3's max errors beside the paper's, the joint stiffnesses with 95 % intervals,
    Table 1's status and values, the model error (:func:`model_error_text`) and the diagnosis verdict."""
    errors = "; ".join(f"{s.replace('_', '-')} {t.relative_error_pct.abs().max():.1f} % "
                       f"(paper {t.paper_relative_error_pct.abs().max():.1f} %)" for s, t in data["tables"].items())
    items = [{"label": "Natural frequencies (Tables 2, 3)", "lines": [f"Max |error| after identification: {errors}."]},
             {"label": "Joint stiffness, 95 % intervals", "lines": _stiffness_sentences(data)},
             {"label": "Table 1", "lines": [_table1_sentence(data)]}]
    if me := model_error_text(data):
        lead = "Model error, the part"
        items.append({"label": "Model error σ_m", "lines": [("The part" + me[len(lead):]) if me.startswith(lead) else me]})
    items.append({"label": "Diagnosis", "lines": _diagnosis_sentences(data)})
    return items
