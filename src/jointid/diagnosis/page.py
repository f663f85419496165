"""The diagnosis report page: figures (base64 PNG) and the self-contained HTML page.

The page is the jinja2 template ``templates/diagnosis.html`` of this package; its tables are
rendered by :meth:`pandas.DataFrame.to_html` (:func:`html_table`).  See docs/effects.md.
"""

from __future__ import annotations

import base64
import io

import pandas as pd
from jinja2 import Environment, PackageLoader, select_autoescape
from markupsafe import Markup

from jointid.diagnosis.effects import effect_table
from jointid.diagnosis.loop import Diagnosis

RANK_COLUMNS = ["rank", "effect", "removed_fraction", "delta_qaicc", "weight", "support", "explains",
                "indistinguishable_from", "parameter", "estimate", "ci95_low", "ci95_high", "unit",
                "max_abs_error_pct_after", "absorbed", "absorbed_bias_pct", "note"]
TEMPLATE = "diagnosis.html"


def fig_png(fig) -> str:
    """``fig`` as a base64-encoded PNG (110 dpi); the figure is closed."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode()


def figures(res: Diagnosis) -> dict[str, str]:
    """Figures of the report as base64 PNG: ladder, per-mode errors, ranking, point residuals, MAC."""
    import matplotlib

    matplotlib.use("Agg")

    out = {}
    if len(res.ladder):
        out["ladder"] = ladder_figure(res.ladder)
    out["errors"] = errors_figure(res)
    if len(res.ranking):
        out["ranking"] = ranking_figure(res.ranking)
    if len(res.point_residuals):
        out["points"] = points_figure(res.point_residuals)
    for state, M in res.mac.items():
        out[f"mac_{state}"] = mac_figure(state, M)
    return out


def ladder_figure(lad: pd.DataFrame) -> str:
    """Max and RMS error (%) per state along the model ladder (log scale)."""
    import matplotlib.pyplot as plt

    states = list(dict.fromkeys(lad["state"]))
    variants = list(dict.fromkeys(lad["variant"]))
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.4), sharey=False)
    for ax, col, title in zip(axes, ("max_abs_error_pct", "rms_error_pct"), ("max |error|", "RMS error")):
        for s in states:
            g = lad[lad.state == s].set_index("variant").reindex(variants)
            ax.plot(range(len(variants)), g[col], marker="o", label=s)
        ax.set_xticks(range(len(variants)))
        ax.set_xticklabels(variants, rotation=20, ha="right", fontsize=8)
        ax.set_ylabel(f"{title} (%)")
        ax.set_yscale("log")
        ax.grid(True, alpha=0.3)
        ax.set_title(f"model ladder: {title} per state")
    axes[0].legend(fontsize=8)
    return fig_png(fig)


def errors_figure(res: Diagnosis) -> str:
    """Error (%) per paired mode over the measured frequency: reference baseline and current model."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 3.4))
    for (label, df), mk in zip((("baseline calibrated on the reference state", res.compare),
                                ("current model, all states", res.current)), ("o", "s")):
        p = df[df.status == "paired"]
        for s, g in p.groupby("state", sort=False):
            ax.plot(g["freq_meas_Hz"], g["error_pct"], mk, label=f"{label}: {s}", alpha=0.8)
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xlabel("measured frequency (Hz)")
    ax.set_ylabel("(model - measured) / measured (%)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title("where the model fails: error per mode")
    return fig_png(fig)


def ranking_figure(ranking: pd.DataFrame) -> str:
    """Share of the residual each candidate explains to first order (green: its refit explains)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 0.4 * len(ranking) + 1))
    r = ranking.iloc[::-1]
    colors = ["tab:green" if e else "tab:gray" for e in r["explains"]]
    ax.barh(r["effect"], 100 * r["explained_fraction"].fillna(0), color=colors)
    ax.set_xlabel("share of the residual explained to first order (%)")
    ax.set_xlim(0, 100)
    ax.set_title("candidate effects (green: refit reaches the noise level)")
    return fig_png(fig)


def points_figure(point_residuals: pd.DataFrame) -> str:
    """RMS shape residual per measuring point (baseline)."""
    import matplotlib.pyplot as plt

    pr = point_residuals.sort_values("point")
    fig, ax = plt.subplots(figsize=(10, 3))
    ax.bar(pr["point"], pr["rms_residual"], color="tab:orange")
    ax.set_ylabel("RMS shape residual (unit-norm shapes)")
    ax.tick_params(axis="x", rotation=90, labelsize=7)
    ax.set_title("where the shapes fail: residual per measuring point (baseline)")
    return fig_png(fig)


def mac_figure(state: str, M) -> str:
    """MAC matrix of one state, measured modes (rows) against model modes (columns)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.5, 3.6))
    im = ax.imshow(M, vmin=0, vmax=1, cmap="viridis", aspect="auto")
    ax.set_xlabel("model mode")
    ax.set_ylabel("measured mode")
    ax.set_xticks(range(M.shape[1]))
    ax.set_xticklabels(range(1, M.shape[1] + 1), fontsize=6)
    ax.set_yticks(range(M.shape[0]))
    ax.set_yticklabels(range(1, M.shape[0] + 1), fontsize=6)
    fig.colorbar(im, ax=ax, label="MAC")
    ax.set_title(f"MAC, {state} (baseline)")
    return fig_png(fig)


def html_table(df: pd.DataFrame | None, max_rows: int = 200) -> Markup:
    """The first ``max_rows`` rows of ``df`` as an HTML table (4 significant digits), or "none"."""
    if df is None or df.empty:
        return Markup("<p><i>none</i></p>")
    return Markup(df.head(max_rows).to_html(index=False, float_format=lambda v: f"{v:.4g}", na_rep="",
                                            border=0, classes="t"))


def html_page(res: Diagnosis, dataset: str, run: dict) -> str:
    """A readable, self-contained report page (figures embedded).

    Parameters
    ----------
    res : Diagnosis
    dataset : str
        Dataset name shown in the title.
    run : dict
        Run facts: ``time_utc``, ``config_hash``, ``n_dofs`` (each optional).
    """
    lib = pd.DataFrame([{k: v for k, v in r.items() if k != "title"} for r in effect_table()])
    tables = {"compare_summary": res.compare_summary, "compare": res.compare,
              "point_residuals": res.point_residuals.head(12),
              "ranking": res.ranking[[c for c in RANK_COLUMNS if c in res.ranking]], "ladder": res.ladder,
              "parameters": res.parameters, "drift": res.drift, "library": lib,
              "combinations": res.combinations, "next_measurements": res.next_measurements,
              "preload_curve": res.preload_curve}
    env = Environment(loader=PackageLoader("jointid.diagnosis", "templates"),
                      autoescape=select_autoescape(["html"]), keep_trailing_newline=True)
    return env.get_template(TEMPLATE).render(
        figs=figures(res), dataset=dataset, verdict=res.verdict, notes=res.notes, mac_states=list(res.mac),
        model_error=res.model_error.sentence(),
        absorbed=res.absorbed, identifiable=res.identifiable,
        time_utc=run.get("time_utc", ""), config_hash=run.get("config_hash", ""),
        n_dofs=str(run.get("n_dofs", "")), timing=f"{res.timing_s:.0f}",
        tables={k: html_table(v) for k, v in tables.items()})
