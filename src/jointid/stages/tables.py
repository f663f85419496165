"""Rules ``tables`` (Tables 2 and 3: natural frequencies) and ``table1`` (dynamic stiffness), each
beside the paper's values (on the paper's data; on other data the paper columns are empty), as CSV
and Markdown."""

from __future__ import annotations

from typing import TYPE_CHECKING

from jointid import io
from jointid.stages.runner import log

if TYPE_CHECKING:
    from jointid.config.options import Table1Options

PAPER_TABLES = "data/paper/paper_tables.csv"
"""The paper's values of Tables 2-3 (rule ``tables``' input on the paper's data)."""
PAPER_TABLES_COLUMNS = ("state", "order", "paper_simulation_Hz")
PAPER_TABLE1_COLUMNS = ("state", "paper_dynamic_stiffness_N_per_mm", "paper_increase_pct")


def read_paper(path, columns):
    """The paper's values (``data/paper/*.csv``), or an empty table with ``columns`` when the run's
    data are not the paper's (``path`` None or empty)."""
    import pandas as pd

    return io.read_csv(path) if path else pd.DataFrame(columns=list(columns))


def _paper_note(value: float, fmt: str, suffix: str = "") -> str:
    import math

    return "" if value is None or not math.isfinite(float(value)) else f" (paper {value:{fmt}}{suffix})"


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

    from jointid.reporting.tables import markdown_table

    paper = read_paper(paper_csv, PAPER_TABLES_COLUMNS)
    gathered = []
    for state, path in verify_csvs.items():
        unpaired = io.read_csv(unpaired_csvs[state]) if unpaired_csvs else None
        tab = state_table(state, io.read_csv(path), paper, unpaired)
        io.write_csv(tab, outputs[state])
        if unpaired is not None:
            gathered.append(unpaired.assign(state=state))
        md = (markdown or {}).get(state) or outputs[state].replace(".csv", ".md")
        io.write_text(md, markdown_table(tab, state, unpaired))
    if unpaired_out:
        frame = pd.concat(gathered, ignore_index=True) if gathered else pd.DataFrame()
        cols = ["state", "model_mode", "freq_Hz", "target_Hz", "misfit_pct", "visibility_rel", "description"]
        io.write_csv(frame.reindex(columns=cols), unpaired_out)


def state_table(state: str, verified, paper, unpaired=None):
    """One state's table of natural frequencies (Table 2 or 3, :func:`jointid.reporting.tables.frequency_table`)
    of its ``verify.csv`` rows beside the paper's values; logs its largest error (and ``unpaired``'s misfits)."""
    from jointid.reporting.tables import frequency_table

    tab = frequency_table(verified, paper, state)
    worst = tab.relative_error_pct.abs().max()
    misfit = "" if unpaired is None or not len(unpaired) else (
        f"; {len(unpaired)} unpaired visible mode(s), misfit up to {unpaired.misfit_pct.abs().max():.2f} %")
    log(f"table[{state}]: max |error| {worst:.2f} %"
        + _paper_note(tab.paper_relative_error_pct.abs().max(), ".1f", " %") + misfit)
    return tab


def run_table1(stiffness_jsons: list[str], paper_csv: str, out_csv: str, out_md: str, *,
               points_npz: list[str] | None = None, opts: Table1Options | None = None, out_ranges: str | None = None,
               out_cases: str | None = None, out_pairings: str | None = None):
    # many parameters: a workflow stage: one parameter per file of its rule (the Snakefile stays as it is)
    """Rule ``table1``: read the harmonic results, write Table 1 (CSV and Markdown) and, given the
    states' ``drive_points.npz`` (same order as ``stiffness_jsons``), its ranges over the table points
    and the damping laws (``out_ranges``, ``out_cases``: one row per state, point and law; ``opts``: their band and
    number of frequencies, default :meth:`Table1Options.from_config` of no configuration);
    ``out_pairings``: Table 1 under every admissible pairing (the chosen one and each exactly tied
    alternative, :func:`jointid.reporting.tables.table1_pairings_frame`); returns Table 1's frame."""
    import pandas as pd

    from jointid.reporting.tables import reference_state, table1_frame, table1_markdown, table1_pairings_frame

    docs = [io.read_json(p) for p in stiffness_jsons]
    df = table1_frame(docs, read_paper(paper_csv, PAPER_TABLE1_COLUMNS))
    pairings = table1_pairings_frame(docs)
    if out_pairings:
        io.write_csv(pairings, out_pairings)
    ranges = None
    if points_npz:
        if opts is None:
            from jointid.config.options import Table1Options

            opts = Table1Options.from_config(None)
        ranges, cases = table1_ranges(docs, points_npz, reference_state(list(df.state)), opts,
                                      dict(zip(df.state, df.paper_increase_pct)))
        io.write_csv(ranges, out_ranges)
        if out_cases:
            io.write_csv(cases, out_cases)
    io.write_csv(df, out_csv)
    io.write_text(out_md, table1_markdown(df, ranges, pairings))
    for _, r in df.iterrows():
        inc = ("" if pd.isna(r.increase_pct)
               else f", increase {r.increase_pct:+.1f} %" + _paper_note(r.paper_increase_pct, "+.1f", " %"))
        pinc = "" if pd.isna(r.paired_increase_pct) else f", increase {r.paired_increase_pct:+.1f} %"
        log(f"table1[{r.state}]: {r.status}; band minimum {r.dynamic_stiffness_N_per_mm:,.0f} N/mm (not identified: "
            f"{r.not_identified_dynamic_stiffness_N_per_mm:,.0f}), lowest paired peak "
            f"{r.paired_dynamic_stiffness_N_per_mm:,.0f} N/mm{pinc}"
            + _paper_note(r.paper_dynamic_stiffness_N_per_mm, ",.0f") + inc
            + ("; over the identified damping's 95 % intervals, governing mode at" if getattr(r, "damping_source", "")
               == "identified" else "; at damping ratio") + f" {r.damping_ratio_low:g}-{r.damping_ratio_high:g}: band minimum "
              f"{r.k_dyn_min_low_N_per_mm:,.0f}-{r.k_dyn_min_high_N_per_mm:,.0f} N/mm"
            + (f"; tied pairings chosen by {r.tie_rule}" if r.tie_rule and r.tie_rule != "least cost (no tie)" else ""))
    for r in pairings[pairings.pairing != "chosen"].itertuples():
        log(f"table1[{r.state}] under the {r.pairing} pairing: {r.status}; band minimum {r.k_dyn_min_N_per_mm:,.0f} N/mm")
    for r in (ranges.itertuples() if ranges is not None else []):
        log(f"table1 range[{r.state}, {r.basis}, {r.over}]: increase {r.increase_low_pct:+.1f} … "
            f"{r.increase_high_pct:+.1f} %" + _paper_note(r.paper_increase_pct, "+.1f",
                                                          f" % {'inside' if r.paper_inside else 'outside'}"))
    return df


def table1_ranges(docs: list[dict], points_npz: list[str], reference: str, opts: Table1Options, paper_increase: dict):
    """The ranges of Table 1 (:func:`jointid.response.ranges.range_table`) and their cases.

    The three damping laws are calibrated on the reference state's drive point: the mode that sets its
    lowest paired resonance peak (else its band minimum) gets the damping ratio the configured model
    gives it; the band is ``opts``' (None: the reference state's).  Returns ``(ranges, cases)``."""
    import numpy as np
    import pandas as pd

    from jointid.response.ranges import LAWS, calibrate, case_table, range_table

    data = {d["state"]: dict(io.load_npz(p)) for d, p in zip(docs, points_npz)}
    doc = next(d for d in docs if d["state"] == reference)
    cal = doc.get("paired_minimum") or doc["governing_mode"]
    r = int(cal["fe_mode"]) - 1
    ref = data[reference]
    laws = {law: calibrate(law, float(cal["damping_ratio"]), float(ref["freqs_Hz"][r]), float(ref["joint_share"][r]))
            for law in LAWS}
    band = doc["band_Hz"] if opts.band_Hz is None else opts.band_Hz
    cases = {s: case_table(d, laws, band_Hz=band, n_freq=opts.n_freq) for s, d in data.items()}
    ranges = range_table(cases, reference, doc["drive_point"], paper_increase)
    for law, v in laws.items():
        log(f"table1: damping law {law} calibrated on FE mode {r + 1} ({ref['freqs_Hz'][r]:.1f} Hz, joint share "
            f"{ref['joint_share'][r]:.3f}) of {reference} at {doc['drive_point']}: parameter {v:.4g}")
    return ranges, pd.concat([c.assign(state=s) for s, c in cases.items()], ignore_index=True)
