"""Write the README's results table from a reproduction's results (not typed by hand).

    python tools/readme_results.py [--results results] [--readme README.md]

Replaces the lines between ``<!-- numbers: regenerate -->`` and ``<!-- /numbers -->`` with a table
read from ``results/tables``, ``results/identify/<state>/params.json``, ``results/hypotheses`` (with
``next_measurements.csv``) and
``results/diagnosis/paper``.  Exits 2 with a message when a file is missing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

from jointid.identification.record import IdentificationRecord

START, END = "<!-- numbers: regenerate -->", "<!-- /numbers -->"
STATES = ("power_off", "power_on")


def _pct(v: float, fmt: str = ".2f") -> str:
    return "–" if pd.isna(v) else f"{v:{fmt}} %"


def table(results: Path) -> list[str]:
    """The README's results table (Markdown lines) from ``results``."""
    t = {s: pd.read_csv(results / "tables" / f"table{n}_{s}.csv") for n, s in ((2, "power_off"), (3, "power_on"))}
    t1 = pd.read_csv(results / "tables" / "table1_dynamic_stiffness.csv").set_index("state")
    par = {s: IdentificationRecord.read(results / "identify" / s / "params.json") for s in STATES}
    rows = [("max \\|relative error\\|, the six paired modes",
             [_pct(t[s]["relative_error_pct"].abs().max()) for s in STATES]),
            ("same, the paper's model (from its tabled frequencies)", [_pct(t[s]["paper_relative_error_pct"].abs().max(), ".1f") for s in STATES]),
            ("model error σ_m per mode (χ²/dof at the stated 1 %)",
             [f"{p.model_error['sigma_model_pct']:.1f} % ({p.model_error['c_hat']:.0f})"
              if p.model_error else "–" for p in par.values()])]
    cells = []
    for s in STATES:
        r = t1.loc[s]
        ident = r["status"] == "identified"
        k = r["dynamic_stiffness_N_per_mm"] if ident else r["not_identified_dynamic_stiffness_N_per_mm"]
        cell = f"**{r['status']}**: {k:,.0f} N/mm"
        if "k_dyn_min_low_N_per_mm" in r and pd.notna(r["k_dyn_min_low_N_per_mm"]):
            cell += f" [{r['k_dyn_min_low_N_per_mm']:,.0f}–{r['k_dyn_min_high_N_per_mm']:,.0f} over ζ]"
        if pd.notna(r.get("increase_pct")):
            cell += f" ({r['increase_pct']:+.1f} %; paper {r['paper_increase_pct']:+.1f} %)"
        cells.append(cell)
    rows.append(("Table 1: minimum dynamic stiffness", cells))
    out = ["| | power-off (Table 2) | power-on (Table 3) |", "|---|---|---|"]
    out += [f"| {name} | {a} | {b} |" for name, (a, b) in rows]
    hyp = results / "hypotheses" / "ranking.csv"
    if hyp.exists():
        h = pd.read_csv(hyp)
        ranked = h[h["rank"].notna()]
        best = ranked.iloc[0]
        near = ranked[ranked["delta_qaicc"] < 4.0]["hypothesis"].tolist()
        out += ["", f"Both states at once (linked contact law): best reconstruction **{best['hypothesis']}**, "
                f"σ_m = {best['sigma_model_pct']:.1f} % per mode. Within ΔQAICc < 4: {', '.join(near)} "
                f"({len(near)} of {len(ranked)} ranked; {len(h) - len(ranked)} listed apart)."]
    nxt = results / "hypotheses" / "next_measurements.csv"
    if nxt.exists() and nxt.stat().st_size > 1:
        n = pd.read_csv(nxt)
        if len(n):
            b, t = n.iloc[0], n.iloc[0]["target"]
            out += ["", f"Next measurement: **{b['measurement']}** (1σ {b['sigma_pct']:.1f} %): {t} over the admissible "
                    f"hypotheses ×{b[t + '_ratio_before']:.2f} → ×{b[t + '_ratio_after']:.2f} expected, "
                    f"{b['expected_hypotheses_left']:.1f} of {int(b['admissible_hypotheses'])} hypotheses left."]
    verdict = results / "diagnosis" / "paper" / "ranking.csv"
    if verdict.exists():
        r = pd.read_csv(verdict).iloc[0]
        if pd.notna(r.get("delta_qaicc")):
            out += ["", f"Diagnosis: **{r['effect']}** removes {100 * r['removed_fraction']:.0f} % of the misfit, "
                    f"{r['support']} supported (ΔQAICc {r['delta_qaicc']:.1f}); max error after "
                    f"{r['max_abs_error_pct_after']:.2f} %."]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", default="results")
    ap.add_argument("--readme", default="README.md")
    a = ap.parse_args(argv)
    readme = Path(a.readme)
    text = readme.read_text()
    if START not in text or END not in text:
        print(f"{readme}: no {START} ... {END} block to fill", file=sys.stderr)
        return 2
    try:
        lines = table(Path(a.results))
    except FileNotFoundError as exc:
        print(f"{exc.filename}: missing — run `make reproduce` first", file=sys.stderr)
        return 2
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    readme.write_text(head + START + "\n" + "\n".join(lines) + "\n" + END + tail)
    print(f"{readme}: results table written from {a.results}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
