"""Rules ``tables`` (Tables 2 and 3: natural frequencies) and ``table1`` (dynamic stiffness), each
beside the paper's values, as CSV and Markdown."""

from __future__ import annotations

from jointid import io
from jointid.stages.runner import log


def run_tables(verify_csvs: dict[str, str], paper_csv: str, outputs: dict[str, str],
               markdown: dict[str, str] | None = None) -> None:
    """Tables 2 and 3: our FE-verified frequencies beside the paper's.

    ``outputs`` and ``markdown`` (default: the CSV path with ``.md``) name each state's table files.
    """
    import pandas as pd

    from jointid.reporting.tables import frequency_table, markdown_table

    paper = pd.read_csv(paper_csv)
    for state, path in verify_csvs.items():
        tab = frequency_table(pd.read_csv(path), paper, state)
        io.write_csv(tab, outputs[state])
        md = (markdown or {}).get(state) or outputs[state].replace(".csv", ".md")
        io.write_text(md, markdown_table(tab, state))
        log(f"table[{state}]: max |error| {tab.relative_error_pct.abs().max():.2f} % "
            f"(paper {tab.paper_relative_error_pct.abs().max():.1f} %)")


def run_table1(stiffness_jsons: list[str], paper_csv: str, out_csv: str, out_md: str):
    """Rule ``table1``: read the harmonic results, write Table 1 (CSV and Markdown); returns its frame."""
    import pandas as pd

    from jointid.reporting.tables import table1_frame, table1_markdown

    docs = [io.read_json(p) for p in stiffness_jsons]
    df = table1_frame(docs, pd.read_csv(paper_csv))
    io.write_csv(df, out_csv)
    io.write_text(out_md, table1_markdown(df))
    for _, r in df.iterrows():
        inc = ("" if pd.isna(r.increase_pct)
               else f", increase {r.increase_pct:+.1f} % (paper {r.paper_increase_pct:+.1f} %)")
        log(f"table1[{r.state}]: {r.dynamic_stiffness_N_per_mm:,.0f} N/mm (paper "
            f"{r.paper_dynamic_stiffness_N_per_mm:,.0f}){inc}")
    return df
