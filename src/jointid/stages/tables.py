"""Rules ``tables`` (Tables 2 and 3: natural frequencies) and ``table1`` (dynamic stiffness), each
beside the paper's values, as CSV and Markdown."""

from __future__ import annotations

from jointid import io
from jointid.stages.runner import log


def run_tables(verify_csvs: dict[str, str], paper_csv: str, outputs: dict[str, str],
               markdown: dict[str, str] | None = None, unpaired_csvs: dict[str, str] | None = None,
               unpaired_out: str | None = None) -> None:
    """Tables 2 and 3: our FE-verified frequencies beside the paper's.

    ``outputs`` and ``markdown`` (default: the CSV path with ``.md``) name each state's table files.
    ``unpaired_csvs``: each state's model modes that the test would clearly have seen with no measured
    partner (rule ``verify``); listed in the Markdown tables and gathered, with a ``state`` column,
    into ``unpaired_out`` (the misfits the CI gate counts in the max error).
    """
    import pandas as pd

    from jointid.reporting.tables import frequency_table, markdown_table

    paper = pd.read_csv(paper_csv)
    gathered = []
    for state, path in verify_csvs.items():
        tab = frequency_table(pd.read_csv(path), paper, state)
        io.write_csv(tab, outputs[state])
        unpaired = pd.read_csv(unpaired_csvs[state]) if unpaired_csvs else None
        if unpaired is not None:
            gathered.append(unpaired.assign(state=state))
        md = (markdown or {}).get(state) or outputs[state].replace(".csv", ".md")
        io.write_text(md, markdown_table(tab, state, unpaired))
        worst = tab.relative_error_pct.abs().max()
        misfit = "" if unpaired is None or not len(unpaired) else (
            f"; {len(unpaired)} unpaired visible mode(s), misfit up to {unpaired.misfit_pct.abs().max():.2f} %")
        log(f"table[{state}]: max |error| {worst:.2f} % (paper {tab.paper_relative_error_pct.abs().max():.1f} %)"
            + misfit)
    if unpaired_out:
        frame = pd.concat(gathered, ignore_index=True) if gathered else pd.DataFrame()
        cols = ["state", "model_mode", "freq_Hz", "nearest_measured_Hz", "misfit_pct", "visibility_rel", "description"]
        io.write_csv(frame.reindex(columns=cols), unpaired_out)


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
