"""Tables 1-3 of the paper beside ours: CSV frames and Markdown renderings.

* :func:`frequency_table` / :func:`markdown_table` - Tables 2 and 3 (natural frequencies);
* :func:`table1_frame` / :func:`table1_markdown` - Table 1 (minimum dynamic stiffness in the drive
  direction, power-off vs power-on).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from jointid.identification.damping_law import ASSUMED, IDENTIFIED as IDENTIFIED_DAMPING

__all__ = ["REFERENCE_STATE", "TABLE1_COLUMNS", "TABLE_TITLES", "damping_range_cells", "frequency_table",
           "markdown_table", "reference_state", "table1_frame", "table1_markdown", "table1_pairings_frame"]

TABLE_TITLES = {"power_off": "Table 2 — natural frequencies, power-off state",
                "power_on": "Table 3 — natural frequencies, power-on state"}
TABLE1_COLUMNS = ["state", "status", "dynamic_stiffness_N_per_mm", "paper_dynamic_stiffness_N_per_mm",
                  "governing_mode", "static_stiffness_N_per_mm"]
"""The columns the issue asks for, first and in this order; more follow (see :func:`table1_frame`)."""
IDENTIFIED = "identified"
"""``status`` of a state whose band minimum is set by a mode paired with a measured one."""
RANGE_COLUMNS = ["state", "reference_state", "basis", "over", "n_cases", "reference_k_min_low_N_per_mm",
                 "reference_k_min_high_N_per_mm", "k_min_low_N_per_mm", "k_min_high_N_per_mm", "increase_low_pct",
                 "increase_high_pct", "paper_increase_pct", "paper_inside"]
"""Columns of ``table1_ranges.csv`` (:func:`jointid.response.ranges.range_table`)."""
REFERENCE_STATE = "power_off"


def _markdown(cells: pd.DataFrame) -> str:
    """A frame of display strings as a Markdown (pipe) table, cells as given."""
    return cells.to_markdown(index=False, disable_numparse=True, stralign=None, numalign=None)


def frequency_table(verify: pd.DataFrame, paper: pd.DataFrame, state: str) -> pd.DataFrame:
    """Columns ``order, experimental_Hz, simulation_Hz, relative_error_pct, paper_simulation_Hz,
    paper_relative_error_pct`` (errors signed, simulation minus experiment)."""
    p = paper[paper["state"] == state].set_index("order")
    out = verify[["order", "experimental_Hz", "simulation_Hz", "relative_error_pct"]].copy()
    out["paper_simulation_Hz"] = out["order"].map(p["paper_simulation_Hz"]) if len(p) else float("nan")
    out["paper_relative_error_pct"] = (100 * (out["paper_simulation_Hz"] - out["experimental_Hz"])
                                       / out["experimental_Hz"])
    return out


def markdown_table(df: pd.DataFrame, state: str, unpaired: pd.DataFrame | None = None) -> str:
    """Markdown rendering of :func:`frequency_table` (Hz to 0.1, errors in % to 0.01, signed).

    ``unpaired``: the model modes the test would clearly have seen that no measured mode is paired
    with (rule ``verify``'s ``unpaired_visible.csv``); listed below the table, and their misfit
    counts in the max error.
    """
    fmt = {c: (lambda v: f"{int(v)}") if c == "order" else (lambda v: f"{v:.1f}") if c.endswith("_Hz")
           else (lambda v: f"{v:+.2f}") for c in df.columns}
    cells = pd.DataFrame({c: [fmt[c](v) for v in df[c]] for c in df.columns})
    worst = df.relative_error_pct.abs().max()
    lines = [f"# {TABLE_TITLES.get(state, state)}", "", _markdown(cells), ""]
    if unpaired is not None and len(unpaired):
        worst = max(worst, unpaired.misfit_pct.abs().max())
        extra = pd.DataFrame({
            "model mode": [f"{int(v)}" for v in unpaired.model_mode],
            "simulation_Hz": [f"{v:.1f}" for v in unpaired.freq_Hz],
            "target_Hz": [f"{v:.1f}" for v in unpaired.target_Hz],
            "misfit_pct": [f"{v:+.2f}" for v in unpaired.misfit_pct],
            "visibility (weakest paired = 1)": [f"{v:.2f}" for v in unpaired.visibility_rel],
            "description": list(unpaired.description)})
        lines += ["Model modes in the band that the test would clearly have seen, with no measured partner "
                  "(misfits, counted in the max error):", "", _markdown(extra), ""]
    elif unpaired is not None:
        lines += ["Every model mode in the band that the test would clearly have seen is paired.", ""]
    lines += [f"max |relative error|: this model {worst:.2f} %"
              + (" (misfits included)" if unpaired is not None and len(unpaired) else "")
              + f", paper {df.paper_relative_error_pct.abs().max():.2f} %", ""]
    return "\n".join(lines)


def reference_state(states: list[str]) -> str:
    """The state the increase of Table 1 is taken against: power_off, else the first."""
    return REFERENCE_STATE if REFERENCE_STATE in states else states[0]


def table1_frame(stiffness: list[dict], paper: pd.DataFrame) -> pd.DataFrame:
    """Table 1: minimum dynamic stiffness in the drive direction per state, beside the paper's.

    A state is ``identified`` when the mode that sets the minimum of ``|F/X|`` over the band is paired
    with a measured mode (verify stage); then ``dynamic_stiffness_N_per_mm`` holds the minimum.
    Otherwise ``status`` says which unpaired mode governs, ``dynamic_stiffness_N_per_mm`` is empty and
    the model's minimum is in ``not_identified_dynamic_stiffness_N_per_mm``: a number the test never
    saw is not put where it would be read as the result.  ``paired_dynamic_stiffness_N_per_mm`` is
    always the lowest resonance peak of a paired mode.

    Parameters
    ----------
    stiffness : list of dict
        ``dynamic_stiffness.json`` documents of the harmonic stage, one per state.
    paper : DataFrame
        ``data/paper/paper_table1.csv`` (``state, paper_dynamic_stiffness_N_per_mm, paper_increase_pct``).

    Returns
    -------
    DataFrame
        One row per state. Columns :data:`TABLE1_COLUMNS` (``governing_mode`` = FE mode number, 1-based),
        then ``increase_pct`` (vs the reference state, power_off; empty on its row and where a state is
        not identified), ``paper_increase_pct``, ``not_identified_dynamic_stiffness_N_per_mm``,
        ``paired_dynamic_stiffness_N_per_mm``, ``paired_increase_pct``, ``paired_f_at_min_Hz``,
        ``paired_governing_mode``, ``paired_governing_freq_Hz``, ``paired_governing_description``,
        ``paired_governing_measured_order``, ``f_at_min_Hz``, ``governing_freq_Hz``,
        ``governing_description``, ``governing_measured_order``, ``damping_model``,
        ``damping_ratio_governing``, ``drive_point``, ``patch_diameter_m``, ``status_rests_on_tie``
        (a pairing fitting exactly as well as the chosen one would give the other status), ``tie_note``,
        ``tie_rule`` (which rule chose among exactly tied pairings: ``resolvability`` or ``nearest
        partners (fallback: ...)``), and the range over ``harmonic.damping.damping_ratio_range``
        (:func:`damping_range_cells`): ``damping_ratio_low, damping_ratio_high,
        k_dyn_min_low_N_per_mm, k_dyn_min_high_N_per_mm`` (the band minimum, whatever the status),
        ``paired_k_dyn_low_N_per_mm, paired_k_dyn_high_N_per_mm``, ``governing_modes_over_damping_range``,
        then ``increase_low_pct, increase_high_pct`` and ``paired_increase_low_pct,
        paired_increase_high_pct`` (taken at the same damping ratio in both states; the former only
        where both states are identified).  When a state's data carry damping ratios, two more:
        ``damping_source`` (``assumed``, ``measured`` or ``identified``: then every mode has the identified
        law's ratio and the range is over its 95 % intervals, :mod:`jointid.stages.harmonic_damping`) and
        ``damping_note`` (what it is, with the identified values).
    """
    p = paper.set_index("state") if len(paper) else pd.DataFrame()
    df = pd.DataFrame([_table1_row(d, p) for d in stiffness])
    ref = df.state == reference_state(list(df["state"]))
    pk = df["paper_dynamic_stiffness_N_per_mm"]

    def increase(col):
        return np.where(ref, np.nan, 100 * (df[col] / float(df.loc[ref, col].iloc[0]) - 1))

    df.insert(6, "increase_pct", increase("dynamic_stiffness_N_per_mm"))
    df.insert(7, "paper_increase_pct", np.where(ref, np.nan, 100 * (pk / float(pk[ref].iloc[0]) - 1)))
    df.insert(10, "paired_increase_pct", increase("paired_dynamic_stiffness_N_per_mm"))
    for c in ("governing_measured_order", "paired_governing_mode", "paired_governing_measured_order"):
        df[c] = df[c].astype("Int64")
    both = (df["status"] == IDENTIFIED).all()
    grids = {d["state"]: d.get("damping_range") for d in stiffness}
    for col, key, name in (("increase", "k_min_N_per_m", None), ("paired_increase", "k_paired_N_per_m", "chosen")):
        if "damping_ratio_low" not in df:  # no state has a damping range (a harmonic result from before it)
            break
        lo, hi = _increase_range(grids, reference_state(list(df["state"])), key, name)
        df[f"{col}_low_pct"] = [v if (both or name) else math.nan for v in map(lo.get, df["state"])]
        df[f"{col}_high_pct"] = [v if (both or name) else math.nan for v in map(hi.get, df["state"])]
    source = [d["damping"].get("source", ASSUMED) for d in stiffness]
    if any(v != ASSUMED for v in source):  # the data carry damping ratios (frequency-only data: as before)
        df["damping_source"] = source
        df["damping_note"] = [d["damping"].get("text", "") for d in stiffness]
    return df


def _table1_row(d: dict, p: pd.DataFrame) -> dict:
    """One state's row of :func:`table1_frame` before the increases: ``d`` its ``dynamic_stiffness.json``,
    ``p`` the paper's Table 1 indexed by state (empty without it)."""
    g, s, pm = d["governing_mode"], d["state"], d.get("paired_minimum") or {}
    status = d.get("status") or (IDENTIFIED if g.get("measured_order") else "not identified")
    k = d["dynamic_stiffness_N_per_m"] * 1e-3
    return {
        "state": s, "status": status,
        "dynamic_stiffness_N_per_mm": k if status == IDENTIFIED else math.nan,
        "paper_dynamic_stiffness_N_per_mm": float(p.loc[s, "paper_dynamic_stiffness_N_per_mm"])
        if s in p.index else math.nan,
        "governing_mode": int(g["fe_mode"]),
        "static_stiffness_N_per_mm": math.nan if d.get("static_stiffness_N_per_m") is None
        else d["static_stiffness_N_per_m"] * 1e-3,
        "not_identified_dynamic_stiffness_N_per_mm": math.nan if status == IDENTIFIED else k,
        "paired_dynamic_stiffness_N_per_mm": pm.get("dynamic_stiffness_N_per_m", math.nan) * 1e-3,
        "paired_f_at_min_Hz": pm.get("f_at_min_Hz", math.nan),
        "paired_governing_mode": pm.get("fe_mode"),
        "paired_governing_freq_Hz": pm.get("freq_Hz", math.nan),
        "paired_governing_description": pm.get("description", ""),
        "paired_governing_measured_order": pm.get("measured_order"),
        "f_at_min_Hz": d["f_at_min_Hz"],
        "governing_freq_Hz": g["freq_Hz"],
        "governing_description": g["description"],
        "governing_measured_order": g.get("measured_order"),
        "damping_model": d["damping"]["config"].get("model", "modal"),
        "damping_ratio_governing": g["damping_ratio"],
        "drive_point": f"{d['drive_point']}:{d['direction']}",
        "patch_diameter_m": d.get("patch_diameter_m", 0.0),
        "status_rests_on_tie": bool((d.get("tie") or {}).get("rests_on_tie", False)),
        "tie_note": (d.get("tie") or {}).get("note", ""),
        "tie_rule": (d.get("tie") or {}).get("rule", ""),
        **(damping_range_cells(d["damping_range"], "chosen") if d.get("damping_range") else {}),
    }


def damping_range_cells(rng: dict | None, pairing: str) -> dict:
    """Table 1's cells of the damping-ratio range (``dynamic_stiffness.json``'s ``damping_range``,
    :func:`jointid.response.ranges.damping_ratio_range`) under one ``pairing`` (``"chosen"``, ``"tied 1"``,
    ...): ``damping_ratio_low/high`` (dimensionless), ``k_dyn_min_low/high_N_per_mm`` (the band
    minimum), ``paired_k_dyn_low/high_N_per_mm`` (the lowest paired peak) and
    ``governing_modes_over_damping_range`` (the FE modes that set the band minimum over the range)."""
    nan = math.nan
    if not rng:
        return {"damping_ratio_low": nan, "damping_ratio_high": nan, "k_dyn_min_low_N_per_mm": nan,
                "k_dyn_min_high_N_per_mm": nan, "paired_k_dyn_low_N_per_mm": nan, "paired_k_dyn_high_N_per_mm": nan,
                "governing_modes_over_damping_range": ""}
    p = (rng.get("paired") or {}).get(pairing) or {}
    mm = lambda v: nan if v is None else float(v) * 1e-3  # noqa: E731
    return {"damping_ratio_low": rng["damping_ratio_low"], "damping_ratio_high": rng["damping_ratio_high"],
            "k_dyn_min_low_N_per_mm": mm(rng["k_min_low_N_per_m"]), "k_dyn_min_high_N_per_mm": mm(rng["k_min_high_N_per_m"]),
            "paired_k_dyn_low_N_per_mm": mm(p.get("k_paired_low_N_per_m")),
            "paired_k_dyn_high_N_per_mm": mm(p.get("k_paired_high_N_per_m")),
            "governing_modes_over_damping_range": " ".join(str(m) for m in dict.fromkeys(rng["governing_fe_mode"]))}


def _increase_range(grids: dict, ref: str, key: str, pairing: str | None) -> tuple[dict, dict]:
    """Lowest and highest increase (%) of each state over the reference, taken at each damping ratio of
    the grid in both states (``key`` of the range, or of its ``pairing``'s paired record); NaN where a
    value is missing; the reference's own row NaN."""
    def values(g):
        if not g:
            return None
        v = g[key] if pairing is None else ((g.get("paired") or {}).get(pairing) or {}).get(key)
        return None if v is None else np.array([math.nan if x is None else x for x in v], float)

    lo, hi = {}, {}
    a = values(grids.get(ref))
    for s, g in grids.items():
        b = values(g)
        inc = (100 * (b / a - 1) if s != ref and a is not None and b is not None and a.size == b.size
               else np.array([math.nan]))
        inc = inc[np.isfinite(inc)]
        lo[s], hi[s] = (float(inc.min()), float(inc.max())) if inc.size else (math.nan, math.nan)
    return lo, hi


def table1_pairings_frame(stiffness: list[dict]) -> pd.DataFrame:
    """Table 1 under every admissible pairing: one row per state and pairing (``chosen``, then each
    exactly tied alternative, ``tied 1``, ...; ``dynamic_stiffness.json``'s ``pairings``).

    Columns ``state, pairing, status, k_dyn_min_N_per_mm`` (the band minimum: the same model, so the
    same number under every pairing; the status says whether the mode that sets it is paired),
    ``governing_mode, governing_measured_order, paired_dynamic_stiffness_N_per_mm, paired_governing_mode,
    paired_governing_measured_order``, the damping range (:func:`damping_range_cells`),
    ``increase_pct`` (vs the reference state under the same pairing, where both are identified) and
    ``tie_rule`` (which rule chose the ``chosen`` one).
    """
    rows = []
    for d in stiffness:
        for p in d.get("pairings") or [{"pairing": "chosen", "status": d.get("status", ""),
                                        "paired_minimum": d.get("paired_minimum"),
                                        "governing_measured_order": d["governing_mode"].get("measured_order")}]:
            pm = p.get("paired_minimum") or {}
            rows.append({"state": d["state"], "pairing": p["pairing"], "status": p["status"],
                         "k_dyn_min_N_per_mm": d["dynamic_stiffness_N_per_m"] * 1e-3,
                         "governing_mode": int(d["governing_mode"]["fe_mode"]),
                         "governing_measured_order": p.get("governing_measured_order"),
                         "paired_dynamic_stiffness_N_per_mm": pm.get("dynamic_stiffness_N_per_m", math.nan) * 1e-3,
                         "paired_governing_mode": pm.get("fe_mode"),
                         "paired_governing_measured_order": pm.get("measured_order"),
                         **damping_range_cells(d.get("damping_range"), p["pairing"]),
                         "tie_rule": (d.get("tie") or {}).get("rule", "")})
    df = pd.DataFrame(rows)
    for c in ("governing_measured_order", "paired_governing_mode", "paired_governing_measured_order"):
        df[c] = df[c].astype("Int64")
    ref = reference_state(list(dict.fromkeys(df["state"])))
    base = df[df.state == ref].set_index("pairing")
    ok = lambda r: r.status == IDENTIFIED and r.pairing in base.index and base.loc[r.pairing, "status"] == IDENTIFIED  # noqa: E731
    df["increase_pct"] = [100 * (r.k_dyn_min_N_per_mm / base.loc[r.pairing, "k_dyn_min_N_per_mm"] - 1)
                          if r.state != ref and ok(r) else math.nan for r in df.itertuples()]
    return df


def _num(v, fmt: str, empty: str = "—") -> str:
    return empty if pd.isna(v) else format(v, fmt)


def _table1_cells(r) -> dict:
    order = lambda v: "" if pd.isna(v) else f", measured mode {int(v)}"  # noqa: E731
    static = "n/a (K singular)" if pd.isna(r.static_stiffness_N_per_mm) else f"{r.static_stiffness_N_per_mm:,.0f}"
    unpaired = ("" if pd.isna(r.not_identified_dynamic_stiffness_N_per_mm)
                else f" (not identified: {r.not_identified_dynamic_stiffness_N_per_mm:,.0f})")
    paired = ("none" if pd.isna(r.paired_governing_mode) else
              f"{r.paired_dynamic_stiffness_N_per_mm:,.0f} (FE mode {r.paired_governing_mode}, "
              f"{r.paired_governing_freq_Hz:.0f} Hz, {r.paired_governing_description}"
              f"{order(r.paired_governing_measured_order)})")
    return {"state": r.state, "status": r.status,
            "dynamic stiffness (N/mm)": _num(r.dynamic_stiffness_N_per_mm, ",.0f") + unpaired,
            "paper (N/mm)": f"{r.paper_dynamic_stiffness_N_per_mm:,.0f}",
            "governing mode": f"FE mode {r.governing_mode} ({r.governing_freq_Hz:.0f} Hz, "
                              f"{r.governing_description}{order(r.governing_measured_order)})",
            "lowest peak of a paired mode (N/mm)": paired,
            **({_zeta_header(r): _span(r.k_dyn_min_low_N_per_mm, r.k_dyn_min_high_N_per_mm)
                + f" (paired peak {_span(r.paired_k_dyn_low_N_per_mm, r.paired_k_dyn_high_N_per_mm)})"}
               if "k_dyn_min_low_N_per_mm" in r else {}),
            "static stiffness (N/mm)": static}


def _identified(r) -> bool:
    return getattr(r, "damping_source", ASSUMED) == IDENTIFIED_DAMPING


def _zeta_header(r) -> str:
    if _identified(r):
        return "band minimum over the identified damping's 95 % intervals (N/mm)"
    return f"band minimum at ζ {_num(r.damping_ratio_low, 'g')}–{_num(r.damping_ratio_high, 'g')} (N/mm)"


def _span(lo, hi) -> str:
    return f"{_num(lo, ',.0f')}–{_num(hi, ',.0f')}"


def pairings_markdown(pairings: pd.DataFrame | None) -> list[str]:
    """Markdown lines of :func:`table1_pairings_frame`: Table 1 under every admissible pairing."""
    if pairings is None or pairings.empty or (pairings["pairing"] == "chosen").all():
        return []
    cells = pd.DataFrame([{
        "state": r.state, "pairing": r.pairing, "status": r.status,
        "band minimum (N/mm)": f"{r.k_dyn_min_N_per_mm:,.0f}", _zeta_header(r): _span(r.k_dyn_min_low_N_per_mm,
                                                                                       r.k_dyn_min_high_N_per_mm),
        "lowest paired peak (N/mm)": _num(r.paired_dynamic_stiffness_N_per_mm, ",.0f", "none")
        + ("" if pd.isna(r.paired_governing_mode) else f" (FE mode {r.paired_governing_mode})"),
        "increase (%)": _num(r.increase_pct, "+.1f")} for r in pairings.itertuples()])
    rule = pairings.loc[pairings["pairing"] == "chosen", "tie_rule"].iloc[0]
    return ["## Table 1 under every admissible pairing", "", _markdown(cells), "",
            "The pairings fit the measured frequencies exactly alike (same χ², same parameters), so the model and "
            "its band minimum are the same under each; what changes is whether the mode that sets it is paired "
            f"(the status) and the lowest peak of a paired mode. The chosen pairing was chosen by: {rule or 'no rule'}.",
            ""]


def ranges_markdown(ranges: pd.DataFrame) -> list[str]:
    """Markdown lines of ``table1_ranges.csv``: per basis and set of cases, the K_min and increase ranges."""
    if ranges is None or ranges.empty:
        return []
    ref = ranges["reference_state"].iloc[0]
    cells = pd.DataFrame([{
        "state": r.state, "K_min of": r.basis, "over": r.over, "cases": str(r.n_cases),
        f"{ref} (N/mm)": f"{_num(r.reference_k_min_low_N_per_mm, ',.0f')}–{_num(r.reference_k_min_high_N_per_mm, ',.0f')}",
        f"{r.state} (N/mm)": f"{_num(r.k_min_low_N_per_mm, ',.0f')}–{_num(r.k_min_high_N_per_mm, ',.0f')}",
        "increase (%)": f"{_num(r.increase_low_pct, '+.1f')} … {_num(r.increase_high_pct, '+.1f')}",
        f"paper {_num(r.paper_increase_pct, '+.1f')} % inside": "yes" if r.paper_inside in (True, "True") else "no"}
        for r in ranges.itertuples()]).fillna("")
    return ["## Ranges over drive points and damping laws", "", _markdown(cells), "",
            "Cases: the 18 table points (drive and response at the same point, in the drive direction) under each "
            "damping law, and the three laws at the drive point; the increase is taken case by case. The laws are "
            "calibrated so that the reference state's governing paired mode at the drive point has the configured "
            "damping ratio; they differ only in how the damping changes between the states.", ""]


def damping_markdown(df: pd.DataFrame, z: str) -> str:
    """Table 1's note on the damping when the data carry damping ratios: each state's source (``z``: the
    governing modes' ratios)."""
    return ("Damping per state — " + "; ".join(f"{r.state}: {r.damping_note}" for r in df.itertuples())
            + f". Damping ratio of the governing mode: {z}. K_min ≈ 2 ζ_r k_r scales about linearly with it; the "
            "range beside each value is over the identified damping's 95 % intervals where it is identified, over "
            "harmonic.damping.damping_ratio_range (assumed) elsewhere.")


def table1_markdown(df: pd.DataFrame, ranges: pd.DataFrame | None = None, pairings: pd.DataFrame | None = None) -> str:
    """Markdown rendering of :func:`table1_frame` (and of the ranges, and of Table 1 under every
    admissible pairing, :func:`table1_pairings_frame`) with the increases and a note on the damping."""
    drive = df["drive_point"].iloc[0]
    lines = [f"# Table 1 — dynamic stiffness in {drive.split(':')[1].upper()} (drive point {drive.split(':')[0]}, "
             f"patch {1e3 * float(df['patch_diameter_m'].iloc[0]):g} mm)", "",
             _markdown(pd.DataFrame([_table1_cells(r) for _, r in df.iterrows()])), ""]
    ref = reference_state(list(df.state))
    for _, r in df[df.state != ref].iterrows():
        inc = ("not available (a state is not identified)" if pd.isna(r.increase_pct) else f"{r.increase_pct:+.1f} %")
        lines.append(f"**Increase {r.state} vs {ref}: this model {inc}; lowest peaks of paired modes "
                     f"{_num(r.paired_increase_pct, '+.1f')} %; paper {r.paper_increase_pct:+.1f} %.**")
        o_ref = df.loc[df.state == ref, "paired_governing_measured_order"].iloc[0]
        if not (pd.isna(o_ref) or pd.isna(r.paired_governing_measured_order)) and o_ref != r.paired_governing_measured_order:
            lines.append(f"The lowest paired peaks are of different measured modes ({ref}: mode {int(o_ref)}, {r.state}: "
                         f"mode {int(r.paired_governing_measured_order)}), so their ratio is not the stiffening of one mode.")
    if "status_rests_on_tie" in df:
        for _, r in df[df["status_rests_on_tie"].astype(bool)].iterrows():
            lines.append(f"**{r.state}: the status rests on a tie.** {r.tie_note[:1].upper() + r.tie_note[1:]}.")
    for _, r in df[df.state != ref].iterrows():
        if "increase_low_pct" in df and not pd.isna(r.paired_increase_low_pct):
            over = ("Over the identified damping's 95 % intervals (both states at the same end)" if _identified(r) else
                    f"Over ζ {_num(r.damping_ratio_low, 'g')}–{_num(r.damping_ratio_high, 'g')} (the same ratio in both "
                    "states)")
            lines.append(f"{over}: increase {_num(r.increase_low_pct, '+.1f')} … {_num(r.increase_high_pct, '+.1f')} %, "
                         f"lowest paired peaks {_num(r.paired_increase_low_pct, '+.1f')} … "
                         f"{_num(r.paired_increase_high_pct, '+.1f')} %.")
    z = ", ".join(f"{r.state} {r.damping_ratio_governing:.3g}" for _, r in df.iterrows())
    if "damping_source" in df:
        return "\n".join(lines + ["", damping_markdown(df, z), ""] + pairings_markdown(pairings) + ranges_markdown(ranges))
    lines += ["", f"Damping model: `{df.damping_model.iloc[0]}`; damping ratio of the governing mode: {z}. "
              "The minimum dynamic stiffness sits at a resonance, K_min ≈ 2 ζ_r k_r, so its absolute value scales "
              "with the assumed damping (the paper publishes none) and depends on the drive point and on which mode "
              "is excited there; a state is *identified* only when that mode is paired with a measured one.", ""]
    if "damping_ratio_low" in df and df["damping_ratio_low"].notna().any():
        lines += [f"The range beside each value: every mode without a measured damping ratio at one constant modal "
                  f"ratio over harmonic.damping.damping_ratio_range (assumed, typical of bolted rolling-guide machine "
                  f"structures; the paper publishes no damping); K_min ≈ 2 ζ_r k_r scales about linearly with it.", ""]
    return "\n".join(lines + pairings_markdown(pairings) + ranges_markdown(ranges))
