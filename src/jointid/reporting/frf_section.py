"""The report's section on measured FRFs against the model's (issue 40, item 3).

Reads what rule ``harmonic`` writes (:mod:`jointid.stages.frf_compare`; without ``frf.csv`` the files say
"no measured FRF" and the states are left out):
``results/harmonic/<state>/frf_compare.csv``, ``frf_measured_stiffness.json`` and
``frf_overlay_measured.png``.  :func:`load_frf_section` gathers them; :func:`frf_section_html` renders the
fragment (the per-FRF correlation table, the measured drive-point dynamic stiffness beside Table 1's
model value, and the overlay figure of each state); :func:`measured_overlay_figure` draws that figure.
"""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path

import numpy as np
import pandas as pd

from jointid.reporting.figures import STATE_COLOURS, _plt

__all__ = ["MAX_PANELS", "frf_section_html", "load_frf_section", "measured_overlay_figure", "no_frf_figure"]

MAX_PANELS = 6
"""FRFs drawn per state (the drive point first, then in the order of ``frf.csv``)."""
_HEADERS = {"frac": "FRAC", "csac": "CSAC (state)", "csf": "CSF (state)", "log_rms_dB": "log-magnitude RMS (dB)",
            "n_freq": "lines"}


def measured_overlay_figure(curves: list[dict], table: pd.DataFrame, state: str):
    """Measured and model receptance magnitude ``|X/F|`` (µm/N, log scale), one panel per FRF.

    Parameters
    ----------
    curves : list of dict
        :func:`jointid.stages.frf_compare.model_curves`: ``point, direction, f_meas_Hz, H_meas,
        f_model_Hz, H_model`` (Hz, m/N) and ``drive_point``.
    table : DataFrame
        The per-FRF table (``point, direction, frac``) for the panel titles.
    state : str
        Operating state (the suptitle).

    Returns
    -------
    matplotlib.figure.Figure
        Up to :data:`MAX_PANELS` panels, the drive-point FRF first.
    """
    plt = _plt()
    shown = sorted(curves, key=lambda c: not c["drive_point"])[:MAX_PANELS]
    n = len(shown)
    ncol = 1 if n == 1 else 2
    nrow = int(np.ceil(n / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(10 if ncol == 2 else 8, 3.3 * nrow + 0.6), squeeze=False)
    frac = {(r.point, r.direction): r.frac for r in table.itertuples()}
    for ax, c in zip(axes.ravel(), shown):
        ax.semilogy(c["f_meas_Hz"], np.abs(c["H_meas"]) * 1e6, ".", color="k", ms=2.5, label="measured")
        ax.semilogy(c["f_model_Hz"], np.abs(c["H_model"]) * 1e6, color=STATE_COLOURS[0], lw=1.2,
                    label="model (identified)")
        ax.set_title(f"{c['point']}:{c['direction']}{' (drive point)' if c['drive_point'] else ''}, "
                     f"FRAC {frac.get((c['point'], c['direction']), float('nan')):.3f}", fontsize=9)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("receptance |X/F| (µm/N)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(loc="lower left", fontsize=8)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    more = f" ({n} of {len(curves)} FRFs shown)" if len(curves) > n else ""
    fig.suptitle(f"Measured and model FRFs, {state.replace('_', '-')}{more}", y=0.995)
    fig.tight_layout()
    return fig


def no_frf_figure(state: str, note: str):
    """The figure rule ``harmonic`` writes in place of the overlay when the dataset has no measured FRF: one
    panel with ``note``."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 1.2))
    ax.axis("off")
    ax.text(0.5, 0.5, f"{state.replace('_', '-')}: {note}", ha="center", va="center", fontsize=9)
    return fig


def load_frf_section(harmonic_dir, states) -> tuple[pd.DataFrame, dict[str, dict], dict[str, bytes]] | None:
    """The files of :mod:`jointid.stages.frf_compare` under ``harmonic_dir/<state>/`` (``results/harmonic``):
    ``(table, stiffness, figures)`` as :func:`frf_section_html` takes them, for the states that have them;
    None when no state has any (the dataset has no ``frf.csv``)."""
    tables, stiffness, figures = [], {}, {}
    for s in states:
        d = Path(harmonic_dir) / str(s)
        if not (d / "frf_compare.csv").is_file():
            continue
        tab = pd.read_csv(d / "frf_compare.csv")
        if tab.empty:  # written all the same, saying "no measured FRF" (jointid.stages.frf_compare)
            continue
        tables.append(tab)
        if (d / "frf_measured_stiffness.json").is_file():
            stiffness[str(s)] = json.loads((d / "frf_measured_stiffness.json").read_text())
        if (d / "frf_overlay_measured.png").is_file():
            figures[str(s)] = (d / "frf_overlay_measured.png").read_bytes()
    if not tables:
        return None
    return pd.concat(tables, ignore_index=True), stiffness, figures


def _stiffness_rows(stiffness: dict[str, dict]) -> pd.DataFrame:
    rows = []
    for state, d in stiffness.items():
        m = d.get("measured") or {}
        t = d["model_table1"]
        rows.append({"state": state, "drive": f"{d['drive_point']}:{d['direction']}",
                     "measured_N_per_mm": m.get("k_dyn_min_refined_N_per_mm", np.nan),
                     "measured_at_Hz": m.get("f_at_min_refined_Hz", np.nan),
                     "table1_N_per_mm": t["dynamic_stiffness_N_per_mm"], "table1_at_Hz": t["f_at_min_Hz"],
                     "difference_pct": d.get("measured_minus_table1_pct", np.nan)})
    return pd.DataFrame(rows)


def _plain_table(df: pd.DataFrame, formats: dict, headers: dict, text_cols=()) -> str:
    """A frame as a plain HTML table (the fallback when no ``html_table`` is given)."""
    head = "".join(f"<th>{html.escape(headers.get(c, c))}</th>" for c in df.columns)
    body = []
    for _, r in df.iterrows():
        cells = []
        for c in df.columns:
            v = r[c]
            ok = c in text_cols or (isinstance(v, (int, float, np.number)) and np.isfinite(v))
            txt = str(v) if c in text_cols else (format(v, formats.get(c, "")) if ok else "–")
            cells.append(f"<td>{html.escape(txt)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def frf_section_html(table: pd.DataFrame, stiffness: dict[str, dict], figures: dict[str, bytes],
                     html_table=None) -> str:
    """The HTML fragment of measured against model FRFs.

    Parameters
    ----------
    table : DataFrame
        ``frf_compare.csv`` of every state with FRFs, concatenated (:data:`jointid.correlate.frf.COMPARE_COLUMNS`).
    stiffness : {state: dict}
        ``frf_measured_stiffness.json`` of each state.
    figures : {state: bytes}
        ``frf_overlay_measured.png`` of each state (PNG).
    html_table : callable, optional
        ``html_table(df, formats, headers, text_cols=...)`` of the page (:func:`jointid.reporting.page.html_table`);
        default a plain table.

    Returns
    -------
    str
        ``<h3>``, a note on the criteria, the 8-column table, the stiffness table (7 columns) and one
        ``<img>`` (base64 PNG) per state.
    """
    render = html_table or _plain_table
    text = ("state", "point", "direction", "drive")
    fm = {"frac": ".3f", "csac": ".3f", "csf": ".3f", "log_rms_dB": ".2f", "n_freq": "d"}
    out = ["<h3>Measured FRFs against the model's</h3>",
           "<p class='note'>Model: the identified parameters and the harmonic stage's damping, excited as measured "
           "(frf_drive_point). FRAC: shape agreement of one FRF over its lines (1 = equal up to a factor). CSAC and "
           "CSF: agreement over the state's response DOFs at each line (shape; amplitude, 2s/(1+s²) for a model "
           "s times the measurement), averaged over the lines (CSAC is 1 by definition with one FRF). Log-magnitude "
           "RMS: 20·rms(log10|H_model| − log10|H_measured|).</p>",
           render(table, fm, _HEADERS, text_cols=text)]
    if stiffness:
        heads = {"drive": "drive point", "measured_N_per_mm": "measured K_min (N/mm)",
                 "measured_at_Hz": "measured at (Hz)", "table1_N_per_mm": "Table 1 model (N/mm)",
                 "table1_at_Hz": "model at (Hz)",
                 "difference_pct": "measured − model (%)"}
        sfm = {"measured_N_per_mm": ",.0f", "measured_at_Hz": ".1f", "table1_N_per_mm": ",.0f",
               "table1_at_Hz": ".1f", "difference_pct": "+.1f"}
        out.append("<p class='note'>Dynamic stiffness at the drive point read from the measured receptance, "
                   "K(f) = 1/H(f): its minimum over Table 1's band, refined between the measured lines (a parabola "
                   "of |K|² in ω², exact for one mode).</p>")
        out.append(render(_stiffness_rows(stiffness), sfm, heads, text_cols=text))
    for state, png in figures.items():
        out.append(f"<img alt='{html.escape(f'measured and model FRFs, {state}')}' "
                   f"src='data:image/png;base64,{base64.b64encode(png).decode()}'>")
    return "\n".join(out)
