"""The report's section on the identified joint damping of the states (issue 40, item 2).

Renders ``results/tables/joint_damping_states.json`` (:func:`jointid.identification.damping_law.states_comparison`):
each state's structural ratio ζ0 and joint loss factors η with their 95 % intervals, and whether the attraction
changes them (a state against the reference state: the difference, its combined 95 % interval, "changes" only
when that interval excludes 0).  Shown when at least one state's damping is identified.
"""

from __future__ import annotations

import pandas as pd

from jointid.reporting.htmltable import html_table, notes

__all__ = ["damping_section_html", "shown"]

_FM = {"value": ".4g", "ci95_low": ".4g", "ci95_high": ".4g", "change": "+.4g"}
_HEADS = {"ci95_low": "95 % low", "ci95_high": "95 % high", "change": "change"}


def shown(doc: dict | None) -> bool:
    """Whether the report has the section: a state's joint damping is identified."""
    return bool(doc) and any(v.get("identified") for v in doc.get("states", {}).values())


def damping_section_html(doc: dict) -> str:
    """The HTML fragment: the identified values per state, the comparison of the states, and notes."""
    rows = [{"state": s, "parameter": k, **v} for s, st in doc["states"].items() if st.get("identified")
            for k, v in st["parameters"].items()]
    out = ("<p class='note'>Hysteretic law ζ_r = ζ0 + Σ_j η_j e_rj/2 fitted to the measured modal damping ratios, "
           "e_rj the share of mode r's strain energy in the joints of direction j at the identified stiffness. "
           "Table 1 and the model FRFs use the better law of each state.</p>"
           + html_table(pd.DataFrame(rows), _FM, _HEADS, text_cols=("state", "parameter")))
    cmp_rows = [{"state": f"{c['state']} − {c['reference_state']}", "parameter": k, "change": v["change"],
                 "ci95_low": v.get("ci95_low"), "ci95_high": v.get("ci95_high"),
                 "changes": "—" if v["change"] is None else ("yes" if v["changes"] else "no")}
                for c in doc.get("comparisons", []) for k, v in c["parameters"].items()]
    if cmp_rows:
        out += ("<h3>Does the attraction change the joint loss factor?</h3>"
                + html_table(pd.DataFrame(cmp_rows).astype({"change": float, "ci95_low": float, "ci95_high": float}),
                             _FM, _HEADS, text_cols=("state", "parameter", "changes")))
    skipped = [f"{s}: {st.get('note', '')}" for s, st in doc["states"].items() if not st.get("identified")]
    return out + notes([doc["note"]] + skipped)
