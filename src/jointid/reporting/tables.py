"""Tables 1-3 of the paper beside ours: CSV frames and Markdown renderings."""

from __future__ import annotations

import pandas as pd

TABLE_TITLES = {"power_off": "Table 2 — natural frequencies, power-off state",
                "power_on": "Table 3 — natural frequencies, power-on state"}


def frequency_table(verify: pd.DataFrame, paper: pd.DataFrame, state: str) -> pd.DataFrame:
    """Columns ``order, experimental_Hz, simulation_Hz, relative_error_pct, paper_simulation_Hz,
    paper_relative_error_pct`` (errors signed, simulation minus experiment)."""
    p = paper[paper["state"] == state].set_index("order")
    out = verify[["order", "experimental_Hz", "simulation_Hz", "relative_error_pct"]].copy()
    out["paper_simulation_Hz"] = out["order"].map(p["paper_simulation_Hz"]) if len(p) else float("nan")
    out["paper_relative_error_pct"] = (100 * (out["paper_simulation_Hz"] - out["experimental_Hz"])
                                       / out["experimental_Hz"])
    return out


def markdown_table(df: pd.DataFrame, state: str) -> str:
    cols = list(df.columns)
    lines = [f"# {TABLE_TITLES.get(state, state)}", "",
             "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for _, row in df.iterrows():
        cells = [f"{int(v)}" if c == "order" else f"{v:.1f}" if c.endswith("_Hz") else f"{v:+.2f}"
                 for c, v in row.items()]
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", f"max |relative error|: this model {df.relative_error_pct.abs().max():.2f} %, "
              f"paper {df.paper_relative_error_pct.abs().max():.2f} %", ""]
    return "\n".join(lines)
