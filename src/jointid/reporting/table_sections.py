"""The report's sections of the paper's tables: Table 1 (dynamic stiffness) with its ranges, and
Tables 2 and 3 (natural frequencies).

Each table is at most :data:`jointid.reporting.htmltable.MAX_COLUMNS` wide; the long text (status
reasons, mode descriptions, ties) is in notes under it.  Used by :func:`jointid.reporting.page.build_html`.
"""

from __future__ import annotations

import pandas as pd

from jointid.reporting.htmltable import esc, fmt, html_table, notes

__all__ = ["freq_tables_html", "table1_html", "table1_notes"]

TITLES = {"power_off": "Table 2 — power-off", "power_on": "Table 3 — power-on"}


def _mode_text(mode, desc, freq, order) -> str:
    """'FE mode 2: table bounce, 1320 Hz (measured mode 2)' (the measured mode only when paired)."""
    return f"FE mode {mode}: {desc}, {freq:.0f} Hz" + ("" if pd.isna(order) else f" (measured mode {int(order)})")


def table1_notes(t: pd.DataFrame) -> list[str]:
    """Per state: the status in full, the governing mode, the lowest paired peak's mode, the tie
    the status rests on (when it does) and, when the data carry damping ratios, the damping's source."""
    out = []
    for _, r in t.iterrows():
        paired = ("–" if pd.isna(r.paired_governing_mode) else
                  _mode_text(r.paired_governing_mode, r.paired_governing_description, r.paired_governing_freq_Hz,
                             r.paired_governing_measured_order))
        line = (f"{r.state}: {r.status}. Governing mode: "
                f"{_mode_text(r.governing_mode, r.governing_description, r.governing_freq_Hz, r.governing_measured_order)}."
                f" Lowest peak of a paired mode: {paired}.")
        if bool(r.get("status_rests_on_tie", False)):
            line += f" The status rests on a tie: {r.tie_note}."
        if "damping_source" in t:  # the data carry damping ratios
            line += f" Damping ({r.damping_source}): {r.damping_note}."
        out.append(line)
    return out


def _ranges_html(rng: pd.DataFrame) -> str:
    ref = rng["reference_state"].iloc[0]
    span = lambda lo, hi, f, sep="–": f"{fmt(lo, f)}{sep}{fmt(hi, f)}"  # noqa: E731
    cells = pd.DataFrame({
        "state": rng["state"], "K_min of": rng["basis"], "over": rng["over"], "cases": rng["n_cases"],
        f"{ref} lowest–highest (N/mm)": [span(a, b, ",.0f") for a, b in
                                         zip(rng.reference_k_min_low_N_per_mm, rng.reference_k_min_high_N_per_mm)],
        "lowest–highest (N/mm)": [span(a, b, ",.0f") for a, b in zip(rng.k_min_low_N_per_mm, rng.k_min_high_N_per_mm)],
        "increase (%)": [span(a, b, "+.1f", " … ") for a, b in zip(rng.increase_low_pct, rng.increase_high_pct)],
        "paper +42.1 % inside": ["yes" if v in (True, "True") else "no" for v in rng["paper_inside"]]})
    return (html_table(cells, text_cols=("state", "K_min of", "over", "paper +42.1 % inside"))
            + "<p class='note'>Each case: drive and response at one table point (T01…T18) in the drive direction, "
              "over a hammer-tip patch. Damping laws: constant modal ζ; joint dashpots c = η·k_joint (ζ_r = η ω_r e_r / 2, "
              "e_r the mode's strain-energy share in the joints); a constant joint loss factor k_joint(1 + iγ) "
              "(ζ_r ≈ γ e_r / 2). The laws are calibrated so that the reference state's governing paired mode at "
              "the drive point has the configured ratio. So they differ only in how the damping changes between the "
              "states. The increase is taken case by case. 'Paired modes': the lowest resonance peak of a mode "
              "paired with a measured one. 'All modes': the band minimum, whichever mode sets it.</p>")


def table1_html(data: dict) -> str:
    """Table 1 in two tables of at most eight columns (the values; where the minimum sits), its notes,
    and the ranges over the table points and damping laws (folded)."""
    t = data["table1"].copy()
    t["ratio_to_paper"] = t.dynamic_stiffness_N_per_mm / t.paper_dynamic_stiffness_N_per_mm
    t["status_short"] = t["status"].str.split(":").str[0]
    values = ["state", "status_short", "dynamic_stiffness_N_per_mm", "not_identified_dynamic_stiffness_N_per_mm",
              "paper_dynamic_stiffness_N_per_mm", "ratio_to_paper", "increase_pct", "paper_increase_pct"]
    where = ["state", "f_at_min_Hz", "governing_mode", "paired_dynamic_stiffness_N_per_mm", "paired_increase_pct",
             "paired_governing_mode", "damping_ratio_governing", "static_stiffness_N_per_mm"]
    heads = {"status_short": "status", "dynamic_stiffness_N_per_mm": "K_dyn,min identified (N/mm)",
             "not_identified_dynamic_stiffness_N_per_mm": "K_dyn,min not identified (N/mm)",
             "paper_dynamic_stiffness_N_per_mm": "paper (N/mm)", "ratio_to_paper": "ratio to paper",
             "increase_pct": "increase (%)", "paper_increase_pct": "paper increase (%)",
             "f_at_min_Hz": "minimum at (Hz)", "governing_mode": "governing FE mode",
             "paired_dynamic_stiffness_N_per_mm": "lowest peak of a paired mode (N/mm)",
             "paired_increase_pct": "its increase (%)", "paired_governing_mode": "that paired FE mode",
             "damping_ratio_governing": "ζ of the governing mode", "static_stiffness_N_per_mm": "static 1/H(0) (N/mm)"}
    fm = {c: ",.0f" for c in values + where if c.endswith("_N_per_mm")}
    fm.update({"ratio_to_paper": ".2f", "increase_pct": "+.1f", "paper_increase_pct": "+.1f", "paired_increase_pct": "+.1f",
               "f_at_min_Hz": ".1f", "damping_ratio_governing": ".3g", "governing_mode": "d",
               "paired_governing_mode": ".0f"})
    out = (html_table(t[values], fm, heads, text_cols=("state", "status_short"))
           + "<h3>Where the minimum sits</h3>" + html_table(t[where], fm, heads, text_cols=("state",))
           + notes(table1_notes(t)))
    rng = data.get("table1_ranges")
    if rng is not None and len(rng):
        out += ("<details><summary>Ranges over the 18 table points and three damping laws</summary>"
                + _ranges_html(rng) + "</details>")
    return out


def freq_tables_html(data: dict) -> str:
    """Tables 2 and 3 beside the paper's, each with the paired FE mode and its MAC; the FE mode shapes'
    names in a note under each table."""
    out = []
    for state, tab in data["tables"].items():
        t = tab.copy()
        ver = data["verify"].get(state)
        shapes = ""
        if ver is not None:
            t = t.merge(ver[["order", "fe_mode", "mac_to_tracked", "description"]], on="order", how="left")
            shapes = ("FE mode shapes by order: "
                      + "; ".join(f"{int(r.order)} {r.description}" for r in t.itertuples()) + ".")
            t = t.drop(columns="description")
        heads = {"order": "order", "experimental_Hz": "test (Hz)", "simulation_Hz": "this model (Hz)",
                 "relative_error_pct": "error (%)", "paper_simulation_Hz": "paper ANSYS (Hz)",
                 "paper_relative_error_pct": "paper error (%)", "fe_mode": "FE mode", "mac_to_tracked": "MAC to tracked"}
        fm = {"experimental_Hz": ".1f", "simulation_Hz": ".1f", "relative_error_pct": "+.2f",
              "paper_simulation_Hz": ".1f", "paper_relative_error_pct": "+.2f", "mac_to_tracked": ".3f"}
        out.append(f"<div><h3>{esc(TITLES.get(state, state))}</h3>{html_table(t, fm, heads)}"
                   f"{notes([shapes])}</div>")
    return "<div class='row'>" + "".join(out) + "</div>"
