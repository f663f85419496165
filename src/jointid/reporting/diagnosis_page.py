"""The diagnosis report page: the self-contained HTML page, its figures embedded (:mod:`jointid.reporting.diagnosis_figures`).

The page is the jinja2 template ``templates/diagnosis.html`` of this package: a summary card first
(:func:`_summary`, with the errors figure), the details below. Its tables are rendered by
:meth:`pandas.DataFrame.to_html` (:func:`html_table`), at most eight columns wide.  See docs/effects.md.
"""

from __future__ import annotations

import pandas as pd
from jinja2 import Environment, PackageLoader, select_autoescape
from markupsafe import Markup, escape

from jointid.diagnosis.effects import effect_table
from jointid.diagnosis.loop import Diagnosis
from jointid.reporting.diagnosis_figures import figures
from jointid.reporting.diagnosis_summary import short_verdict

RANK_COLUMNS = ["rank", "effect", "removed_fraction", "delta_qaicc", "weight", "support", "explains",
                "indistinguishable_from", "parameter", "estimate", "ci95_low", "ci95_high", "unit",
                "max_abs_error_pct_after", "absorbed", "absorbed_bias_pct", "note"]
TEMPLATE = "diagnosis.html"
MAX_COLUMNS = 8
"""The widest table on the page (columns); wider frames are split, long text goes to notes."""


def _table(df: pd.DataFrame) -> str:
    return df.to_html(index=False, float_format=lambda v: f"{v:.4g}", na_rep="", border=0, classes="t")


def html_table(df: pd.DataFrame | None, max_rows: int = 200, groups: list[list[str]] | None = None, keys: int = 1,
               note_cols=()) -> Markup:
    """The first ``max_rows`` rows of ``df`` as HTML tables of at most :data:`MAX_COLUMNS` columns (4
    significant digits), or "none".

    ``groups``: the columns of each table after the first ``keys`` (the row labels); the columns in no
    group follow in tables of their own. ``note_cols``: long text, listed under the tables per row.
    """
    if df is None or df.empty:
        return Markup("<p><i>none</i></p>")
    df = df.head(max_rows)
    head = list(df.columns[:keys])
    rest = [c for c in df.columns[keys:] if c not in note_cols]
    groups = [[c for c in g if c in rest] for g in (groups or [])]
    left = [c for c in rest if not any(c in g for g in groups)]
    step = MAX_COLUMNS - len(head)
    groups = [g for g in groups if g] + [left[i:i + step] for i in range(0, len(left), step)]
    out = "".join(_table(df[head + g]) for g in groups) or _table(df[head])
    lines = _note_lines(df, head, note_cols)
    if lines:
        out += "<ul class='note'>" + "".join(f"<li>{escape(x)}</li>" for x in lines) + "</ul>"
    return Markup(out)


def _note_lines(df: pd.DataFrame, head: list, note_cols) -> list[str]:
    """The text of ``note_cols`` per row: 'label: text' (one line per row), or with two key columns
    one line per value of the first, 'a: b1 text; b2 text'."""
    lines = []
    for c in (c for c in note_cols if c in df):
        rows = df[df[c].map(lambda v: isinstance(v, str) and bool(v.strip()))]
        if len(head) >= 2:
            lines += [f"{k} — {c}: " + "; ".join(f"{r[head[1]]} {r[c]}" for _, r in g.iterrows())
                      for k, g in rows.groupby(head[0], sort=False)]
        else:
            lines += [f"{r[head[0]]} — {c}: {r[c]}" if head else str(r[c]) for _, r in rows.iterrows()]
    return lines


def _summary(res: Diagnosis) -> list[dict]:
    """The summary card: the verdict, the max errors, the leading candidate and the model error, one
    sentence each (:func:`jointid.reporting.diagnosis_summary.short_verdict`)."""
    from jointid.correlate.pairing import error_summary

    def errors(summary: pd.DataFrame) -> str:
        return ", ".join(f"{r.state} {r.max_abs_error_pct:.2f} %" for r in summary.itertuples())

    items = [{"label": "Verdict", "text": short_verdict(res.explained_by, res.ranking, res.combinations)}]
    text = f"Max |error| of the baseline calibrated on the reference state: {errors(res.compare_summary)}"
    if len(res.current) and "status" in res.current:
        text += f"; of the current model on all states: {errors(error_summary(res.current))}"
    items.append({"label": "Errors", "text": text + "."})
    if len(res.ranking) and "estimate" in res.ranking:
        r = res.ranking.iloc[0]
        ci = ("" if pd.isna(r.get("ci95_low")) else f" (95 %: {r['ci95_low']:.3g} … {r['ci95_high']:.3g})")
        unit = "" if str(r.get("unit", "-")) in ("-", "", "nan") else f" {r['unit']}"
        items.append({"label": "Leading candidate",
                      "text": f"{r['effect']}: {r['parameter']} = {r['estimate']:.3g}{ci}{unit}; "
                              f"refitted, the max error is {r['max_abs_error_pct_after']:.2f} %."})
    items.append({"label": "Model error σ_m", "text": res.model_error.sentence()})
    return items


def html_page(res: Diagnosis, dataset: str, run: dict, figs: dict[str, str] | None = None) -> str:
    """A readable, self-contained report page (figures embedded): a summary card first, the details
    below.

    Parameters
    ----------
    res : Diagnosis
    dataset : str
        Dataset name shown in the title.
    run : dict
        Run facts: ``time_utc``, ``config_hash``, ``n_dofs`` (each optional).
    figs : dict, optional
        :func:`figures` of ``res`` when made already (in a process of their own); else made here.
    """
    lib = pd.DataFrame([{k: v for k, v in r.items() if k != "title"} for r in effect_table()])
    rank = ["rank", "effect"]
    tables = {"compare_summary": html_table(res.compare_summary),
              "compare": html_table(res.compare, keys=2, note_cols=("description",)),
              "point_residuals": html_table(res.point_residuals.head(12)),
              "ranking": html_table(res.ranking[[c for c in RANK_COLUMNS if c in res.ranking]], keys=2,
                                    groups=[RANK_COLUMNS[2:7], RANK_COLUMNS[8:14], RANK_COLUMNS[14:16] + [RANK_COLUMNS[7]]],
                                    note_cols=("note",)) if set(rank) <= set(res.ranking) else html_table(res.ranking),
              "ladder": html_table(res.ladder, keys=2, groups=[["n_paired", "n_unpaired_visible", "max_abs_error_pct",
                                                                 "rms_error_pct"]]),
              "parameters": html_table(res.parameters, keys=2), "drift": html_table(res.drift, keys=2),
              "library": html_table(lib, note_cols=("description",)),
              "combinations": html_table(res.combinations, groups=[["n_effects", "delta_aicc", "delta_qaicc", "weight",
                                                                    "support", "removed_fraction", "explains"]],
                                         note_cols=("estimates",)),
              "next_measurements": html_table(res.next_measurements), "preload_curve": html_table(res.preload_curve)}
    env = Environment(loader=PackageLoader("jointid.reporting", "templates"),
                      autoescape=select_autoescape(["html"]), keep_trailing_newline=True)
    return env.get_template(TEMPLATE).render(
        figs=figures(res) if figs is None else figs, dataset=dataset, verdict=res.verdict, notes=res.notes, mac_states=list(res.mac),
        summary=_summary(res), model_error=res.model_error.sentence(),
        absorbed=res.absorbed, identifiable=res.identifiable,
        time_utc=run.get("time_utc", ""), config_hash=run.get("config_hash", ""),
        n_dofs=str(run.get("n_dofs", "")), timing=f"{res.timing_s:.0f}", tables=tables)
