"""The key box at the top of the report page: the numbers a reader looks for first.

* :func:`key_numbers` - Table 1 (status, identified value or why not, the lowest paired peak), its
  increases, the ranges, the frequency errors, the damping, Table 1's problems and the model error,
  as the template ``page.html.j2`` renders them;
* :func:`model_error_text` - the model error of each state's fit and of the best reconstruction
  hypothesis, in one sentence.

The page around it is :func:`jointid.reporting.page.build_html`.
"""

from __future__ import annotations

import pandas as pd

__all__ = ["key_numbers", "model_error_text"]


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
        "problems": data.get("table1_problems", []),
        "model_error": model_error_text(data),
    }


def model_error_text(data: dict) -> str:
    """The model error of each state's identification, and of the hypotheses' comparison when there is
    one: the fit's remaining error per mode beside the stated noise (docs/effects.md, "Statistics")."""
    parts = []
    for state, p in data["params"].items():
        me = p.get("model_error")
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
