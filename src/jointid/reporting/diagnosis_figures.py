"""The diagnosis page's figures (base64 PNG): the model ladder, the error per mode, the candidates' shares,
the shape residual per point and the MAC matrices (:func:`figures`).

A module of its own, light (pandas and matplotlib): the figures can be drawn in a process of their own from
a :class:`FigureData` (:func:`jointid.stages.diagnosis.run_diagnosis`), which imports only this.
"""

from __future__ import annotations

import base64
import io
from dataclasses import dataclass
from typing import TYPE_CHECKING

import pandas as pd

if TYPE_CHECKING:
    from jointid.diagnosis.loop import Diagnosis


def fig_png(fig) -> str:
    """``fig`` as a base64-encoded PNG (110 dpi); the figure is closed."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode()


@dataclass(frozen=True)
class FigureData:
    """What the page's figures show of a :class:`~jointid.diagnosis.loop.Diagnosis` (its fields of the same
    names): small and picklable, for a figure process of its own (:func:`jointid.stages.diagnosis.run_diagnosis`)."""

    ladder: pd.DataFrame
    compare: pd.DataFrame
    current: pd.DataFrame
    ranking: pd.DataFrame
    point_residuals: pd.DataFrame
    mac: dict


def warm_up() -> None:
    """Draw and encode one small figure: the first one pays for the fonts and the renderer (about 0.4 s),
    which a figure process started ahead then has behind it when asked."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(1, 1))
    ax.plot([0, 1], [0, 1], marker="o", label="x")
    ax.set_xlabel("x")
    ax.legend()
    fig_png(fig)


PRELOAD = ("matplotlib.pyplot", f"{__name__}:warm_up")
"""What a figure process imports and does before it is asked (with ``MPLBACKEND=Agg``)."""


def figures(res: Diagnosis | FigureData) -> dict[str, str]:
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


def errors_figure(res: Diagnosis | FigureData) -> str:
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
