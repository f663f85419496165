"""The report section of the reconstruction hypotheses and the linked two-state fit.

Reads the records of :mod:`jointid.stages.hypotheses` (``results/hypotheses/``): the QAICc ranking,
the best hypothesis's linked fit (contact law parameters with intervals, frequencies of both states
beside the measurement and the paper's per-state method), the spread of the joint parameters over
the admissible hypotheses and the measurement that would narrow it (next_measurements.csv).
"""

from __future__ import annotations

import html

import pandas as pd

__all__ = ["hypotheses_html", "linked_frequency_table", "next_measurement_html", "LAW_TEXT"]

LAW_TEXT = ("k = k0·((P + F_c)/(P + F_c,0))^β per carriage in X and Y, F_c the carriage load (statics load share "
            "of the motor attraction and the carried weight), P the block preload (best catalogue class); the "
            "feed stiffness k_feed is one servo/brake term for both states")


def linked_frequency_table(rec: dict, paper_tables: dict | None = None, ranges: pd.DataFrame | None = None) -> pd.DataFrame:
    """Measured and linked-fit frequencies of every state of a hypothesis record, with the range of the
    error over the admissible reconstructions when ``ranges`` (reconstruction.csv) is given and the
    paper's per-state method beside them when ``paper_tables`` (state -> Table 2/3 frame) is given."""
    rows = []
    err = {} if ranges is None else {(r.state, int(r.mode)): (r.value_min, r.value_max)
                                     for r in ranges[ranges["quantity"] == "error"].itertuples()}
    for s in rec["states"]:
        paper = (paper_tables or {}).get(s["state"])
        for i, (fm, f, e) in enumerate(zip(s["f_meas_Hz"], s["f_model_Hz"], s["error_pct"]), start=1):
            row = {"state": s["state"], "mode": i, "test_Hz": fm, "linked_Hz": f, "linked_error_pct": e}
            if (s["state"], i) in err:
                row["error_low_pct"], row["error_high_pct"] = err[(s["state"], i)]
            if paper is not None and "simulation_Hz" in paper and i <= len(paper):
                row["paper_method_Hz"] = paper["simulation_Hz"].iloc[i - 1]
                row["paper_method_error_pct"] = paper["relative_error_pct"].iloc[i - 1]
            rows.append(row)
    return pd.DataFrame(rows)


def _ranking_html(ranking: pd.DataFrame, html_table) -> str:
    """The ranking (at most eight columns), each hypothesis's max errors and misfits per state beside it,
    and the hypotheses' descriptions as notes."""
    esc = html.escape
    cols = ["rank", "hypothesis", "delta_qaicc", "weight", "chi2"]
    cols += [c for c in ("em_preload.beta", "preload_N") if c in ranking.columns]
    errs = [c for c in ranking.columns if c.startswith("max_abs_error_") or c.startswith("unpaired_visible_")]
    fm = {c: ".2f" for c in cols + errs if c != "hypothesis"}
    fm.update({"rank": "d", "weight": ".3f", "chi2": ".1f", "delta_qaicc": ".1f", "em_preload.beta": ".3f",
               "preload_N": ".0f"})
    fm.update({c: "d" for c in errs if c.startswith("unpaired_visible_")})
    heads = {"delta_qaicc": "ΔQAICc", "weight": "weight", "chi2": "χ²", "em_preload.beta": "β", "preload_N": "P (N)"}
    heads |= {c: f"max |error| {c[len('max_abs_error_'):].removesuffix('_pct')} (%)" for c in errs
              if c.startswith("max_abs_error_")}
    heads |= {c: f"unpaired visible, {c[len('unpaired_visible_'):]}" for c in errs if c.startswith("unpaired_visible_")}
    out = [html_table(ranking[cols], fm, heads, text_cols=("hypothesis",), keys=2)]
    if errs:
        out.append("<p class='note'>Each hypothesis's largest frequency error per state, and the clearly visible "
                   "model modes without a measured partner (misfits):</p>"
                   + html_table(ranking[["rank", "hypothesis", *errs]], fm, heads, text_cols=("hypothesis",), keys=2))
    if "description" in ranking:
        out.append("<ul class='note'>" + "".join(f"<li><b>{esc(str(r.hypothesis))}</b>: {esc(str(r.description))}</li>"
                                                 for r in ranking.itertuples()) + "</ul>")
    return "".join(out)


def hypotheses_html(ranking: pd.DataFrame, records: dict, spread: pd.DataFrame | None, html_table,
                    paper_tables: dict | None = None, ranges: pd.DataFrame | None = None,
                    next_meas: pd.DataFrame | None = None) -> str:
    """The section's HTML: one-line calibration statement, ranking, the best hypothesis's linked fit,
    the parameter spread and, with ``next_meas`` (next_measurements.csv), the measurement that would
    narrow the reconstruction (``html_table`` renders a frame)."""
    esc = html.escape
    best = ranking.iloc[0]["hypothesis"]
    rec = records[best]
    sig = ranking.iloc[0].get("sigma_model_pct", 0.0)
    c_hat = ranking.iloc[0].get("c_hat", 1.0)
    out = [f"<p class='note'>Calibration: every hypothesis fitted to both states at once under one contact law ({esc(LAW_TEXT)}); "
           "pairing: one for both states, unpaired clearly visible model modes counted as misfits (in χ² and in the "
           "errors). Ranked by QAICc = χ²_m + 2k + 2k(k+1)/(n−k−1), n the measured frequencies and χ²_m the "
           f"chi-square at the stated noise plus the model error of the best hypothesis, σ_m = {sig:.2g} % per mode "
           f"(χ²/dof = {c_hat:.1f}); hypotheses whose fit is broken are listed apart with the reason.</p>"]
    apart = ranking[ranking["listed_apart"].fillna("").astype(str) != ""] if "listed_apart" in ranking else ranking[:0]
    ranking = ranking.drop(apart.index).astype({"rank": int})
    out.append(_ranking_html(ranking, html_table))
    if len(apart):
        out.append("<p class='note'>Listed apart (a broken reading, not a competitor): "
                   + "; ".join(f"<b>{esc(str(r.hypothesis))}</b>: {esc(str(r.listed_apart))}"
                               for r in apart.itertuples()) + ".</p>")
    par = pd.DataFrame(rec["parameters"])[["parameter", "value", "ci95_low", "ci95_high", "at_bound"]]
    out.append(f"<p class='note'>Best hypothesis <b>{esc(best)}</b> ({esc(rec.get('description', ''))}): "
               f"χ² = {rec['chi2']:.1f} for {rec['n_data']} frequencies and {rec['n_params']} parameters; "
               f"preload class P = {rec['preload_N'] if rec['preload_N'] is not None else '—'} N "
               f"(χ² per class: " + ", ".join(f"{p['preload_N']:g} N → {p['chi2']:.1f} (β {p['beta']:.2f})"
                                               for p in rec.get("preload_profile", [])) + "). 95 % intervals "
               f"scaled by max(1, √(χ²/dof)) = {rec['interval_scale']:.2f}.</p>")
    out.append(html_table(par, {"value": ".4g", "ci95_low": ".4g", "ci95_high": ".4g"},
                          {"ci95_low": "95 % low", "ci95_high": "95 % high"}, text_cols=("parameter",)))
    freq = linked_frequency_table(rec, paper_tables, ranges)
    if {"error_low_pct", "error_high_pct"} <= set(freq.columns):  # one column for the range: eight at most
        freq.insert(freq.columns.get_loc("error_low_pct"), "error_range_pct",
                    [f"{a:.2f} … {b:.2f}" if pd.notna(a) and pd.notna(b) else "–"
                     for a, b in zip(freq.error_low_pct, freq.error_high_pct)])
        freq = freq.drop(columns=["error_low_pct", "error_high_pct"])
    out.append("<p class='note'>Tables 2 and 3 under the linked fit, beside the paper's method (each state "
               "fitted alone, the Tables 2–3 section above). The error range is over the admissible "
               "reconstructions.</p>")
    out.append(html_table(freq, {c: ".2f" for c in freq.columns if c not in ("state", "mode", "error_range_pct")},
                          text_cols=("state",), keys=2))
    if rec.get("unpaired_visible"):
        out.append(html_table(pd.DataFrame(rec["unpaired_visible"]),
                              {"freq_Hz": ".1f", "target_Hz": ".1f", "misfit_pct": ".2f"},
                              text_cols=("state",)))
    if spread is not None and len(spread):
        out.append("<p class='note'>Joint parameters over the admissible hypotheses (within ΔQAICc &lt; 4, or in the 95 % "
                   "confidence set of models: the reconstruction range), their weighted value and the union of their 95 % intervals.</p>")
        names = ("; ".join(f"{r.parameter}: {r.hypotheses}" for r in spread.itertuples())
                 if spread["hypotheses"].nunique() > 1 else str(spread["hypotheses"].iloc[0])) \
            if "hypotheses" in spread else ""
        out.append(html_table(spread.drop(columns="hypotheses", errors="ignore"),
                              {"value_min": ".4g", "value_max": ".4g", "combined_ci95_low": ".4g",
                               "combined_ci95_high": ".4g"}, text_cols=("parameter",)))
        if names:
            out.append(f"<p class='note'>The hypotheses: {esc(names)}.</p>")
    if ranges is not None and len(ranges):
        top = ranges[ranges["mode"] == 0][["quantity", "state", "unit", "value_min", "value_max", "value_weighted",
                                           "n_hypotheses"]]
        out.append("<p class='note'>The answers over the same admissible reconstructions: each joint stiffness "
                   "per state and its change with the motor powered, and Table 1's minimum dynamic stiffness "
                   "(modal superposition of each fit's modes at the nominal damping) and its change. A single "
                   "identified value means little where this range is wide.</p>")
        out.append(html_table(top, {"value_min": ".4g", "value_max": ".4g", "value_weighted": ".4g",
                                    "n_hypotheses": "d"}, {"value_weighted": "weighted"},
                              text_cols=("quantity", "state", "unit")))
    if next_meas is not None and len(next_meas):
        out.append(next_measurement_html(next_meas, html_table))
    return "".join(out)


def next_measurement_html(df: pd.DataFrame, html_table) -> str:
    """The measurement that would narrow the reconstruction (next_measurements.csv, best first): the
    named measurement with the target parameter's range before and after, and the candidates."""
    esc = html.escape
    best = df.iloc[0]
    t = str(best["target"])
    head = (f"<p class='note'><b>The measurement that would narrow the reconstruction: {esc(str(best['measurement']))}</b> "
            f"(1σ {best['sigma_pct']:.1f} %). Over the {int(best['admissible_hypotheses'])} admissible hypotheses "
            f"{esc(t)} spans ×{best[t + '_ratio_before']:.2f}; on synthetic data drawn from them (each taken as the "
            "truth, seeded noise, Akaike weights) this measurement would narrow it to "
            f"×{best[t + '_ratio_after']:.2f} and leave {best['expected_hypotheses_left']:.1f} hypotheses admissible. "
            "No damping ratio is proposed: the hypotheses share one nominal modal damping ratio "
            "(docs/reconstruction.md).</p>")
    cols = ["rank", "measurement", "sigma_pct", "min_delta_chi2", "expected_hypotheses_left", t + "_ratio_after"]
    return head + html_table(df[cols], {"rank": "d", "sigma_pct": ".1f", "min_delta_chi2": ".3g",
                                        "expected_hypotheses_left": ".1f", t + "_ratio_after": ".2f"},
                             {"sigma_pct": "1σ (%)", "min_delta_chi2": "smallest Δχ²",
                              "expected_hypotheses_left": "hypotheses left", t + "_ratio_after": f"{t} range after (×)"},
                             text_cols=("measurement",))
