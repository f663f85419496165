"""Report figures (matplotlib, Agg backend imported inside each function; nothing happens at import).

Every function takes plain data (frames, dicts, arrays) and returns a ``matplotlib.figure.Figure``;
:func:`png_bytes` renders one to PNG.
"""

from __future__ import annotations

import io as _io

import numpy as np
import pandas as pd

STATE_COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e"]
PAPER_COLOUR = "#7f7f7f"


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _label(state: str) -> str:
    return state.replace("_", "-")


def png_bytes(fig, dpi: int = 110) -> bytes:
    """PNG of a figure (and close it)."""
    plt = _plt()
    buf = _io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return buf.getvalue()


def frf_overlay(frfs: dict[str, pd.DataFrame], stiffness: dict[str, dict], paper_N_per_mm: dict[str, float],
                measured_Hz: dict[str, list[float]] | None = None):
    """Drive-point receptance ``|X/F|`` and dynamic stiffness ``|F/X|`` of every state.

    Parameters
    ----------
    frfs : {state: DataFrame}
        ``frf.csv`` tables (``freq_Hz``, ``H_abs_m_per_N``, ``dynamic_stiffness_N_per_m``).
    stiffness : {state: dict}
        ``dynamic_stiffness.json`` documents (minimum and its frequency).
    paper_N_per_mm : {state: float}
        The paper's Table 1 values (N/mm), drawn as dashed lines.
    measured_Hz : {state: list of float}, optional
        Measured natural frequencies (Hz), marked as ticks on the receptance panel.
    """
    plt = _plt()
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(10, 7.8), sharex=True)
    for i, (state, df) in enumerate(frfs.items()):
        c = STATE_COLOURS[i % len(STATE_COLOURS)]
        ax1.semilogy(df["freq_Hz"], df["H_abs_m_per_N"] * 1e6, color=c, lw=1.3, label=f"{_label(state)}, model")
        d = stiffness.get(state)
        label = f"{_label(state)}, model"
        if d:
            kmin = d["dynamic_stiffness_N_per_m"] * 1e-6
            g = d["governing_mode"]
            label += f": min {kmin:.1f} N/µm at {d['f_at_min_Hz']:.0f} Hz (FE mode {g['fe_mode']}, {g['description']})"
            ax2.plot([d["f_at_min_Hz"]], [kmin], "o", color=c, ms=7)
        ax2.semilogy(df["freq_Hz"], df["dynamic_stiffness_N_per_m"] * 1e-6, color=c, lw=1.3, label=label)
        if state in paper_N_per_mm and np.isfinite(paper_N_per_mm[state]):
            ax2.axhline(paper_N_per_mm[state] * 1e-3, color=c, ls="--", lw=1,
                        label=f"{_label(state)}, paper's minimum: {paper_N_per_mm[state] * 1e-3:.1f} N/µm")
    if measured_Hz:
        lo, hi = ax1.get_ylim()
        for i, (state, fm) in enumerate(measured_Hz.items()):
            c = STATE_COLOURS[i % len(STATE_COLOURS)]
            y = hi / (1.6 ** (i + 1))
            ax1.plot(fm, [y] * len(fm), "v", color=c, ms=7, mfc="white", label=f"{_label(state)}, measured modes")
        ax1.set_ylim(lo, hi)
    ax1.set_ylabel("receptance |X/F| (µm/N)")
    ax1.grid(True, which="both", alpha=0.3)
    ax1.legend(loc="lower left", fontsize=8, ncol=2)
    ax2.set_ylabel("dynamic stiffness |F/X| (N/µm)")
    ax2.set_xlabel("frequency (Hz)")
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend(loc="upper left", fontsize=8)
    first = next(iter(stiffness.values()), None)
    if first:
        fig.suptitle(f"Drive-point FRF at {first['drive_point']} in {first['direction'].upper()} "
                     f"(damping model: {first['damping']['config'].get('model', 'modal')})", y=0.995)
    fig.tight_layout()
    return fig


def frequency_errors(tables: dict[str, pd.DataFrame], sigma_pct: dict[str, float]):
    """Per-mode relative frequency error, this model vs the paper's ANSYS model, one panel per state.

    Parameters
    ----------
    tables : {state: DataFrame}
        Tables 2/3 (``order``, ``relative_error_pct``, ``paper_relative_error_pct``).
    sigma_pct : {state: float}
        Measurement uncertainty (1 sigma, %); error bars and the grey band are +-2 sigma.
    """
    plt = _plt()
    n = len(tables)
    fig, axes = plt.subplots(1, n, figsize=(5.2 * n, 4.2), sharey=True, squeeze=False)
    for i, (ax, (state, tab)) in enumerate(zip(axes[0], tables.items())):
        c = STATE_COLOURS[i % len(STATE_COLOURS)]
        x = tab["order"].to_numpy()
        s2 = 2 * sigma_pct.get(state, 0.0)
        ax.axhspan(-s2, s2, color="0.9", zorder=0, label=f"±2σ measurement ({s2:g} %)")
        ax.bar(x - 0.2, tab["relative_error_pct"], 0.4, color=c, yerr=s2, capsize=3, label="this model")
        ax.bar(x + 0.2, tab["paper_relative_error_pct"], 0.4, color=PAPER_COLOUR, hatch="//",
               edgecolor="white", label="paper (ANSYS)")
        ax.axhline(0, color="k", lw=0.8)
        ax.set_xticks(x)
        ax.set_xlabel("measured mode (order)")
        ax.set_title(_label(state))
        ax.grid(True, axis="y", alpha=0.3)
        if i == 0:
            ax.set_ylabel("frequency error, simulation − test (%)")
            ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    return fig


def parameter_intervals(params: dict, bounds: dict[str, tuple[float, float]] | None = None):
    """Identified joint parameters with their 95 % intervals, per state (log scale).

    Parameters
    ----------
    params : {state: jointid.identification.record.IdentificationRecord}
    bounds : {name: (lower, upper)}, optional
        DOE / optimisation bounds (N/m^3), drawn as dotted lines.
    """
    plt = _plt()
    names = next(iter(params.values())).names
    fig, axes = plt.subplots(1, len(names), figsize=(4.2 * len(names), 3.6), squeeze=False)
    for ax, name in zip(axes[0], names):
        for i, (state, doc) in enumerate(params.items()):
            p = doc.interval(name)
            v, lo, hi = p.value, p.ci95_low, p.ci95_high
            ax.errorbar([i], [v], yerr=[[max(v - lo, 0)], [max(hi - v, 0)]], fmt="o", capsize=5, ms=7,
                        color=STATE_COLOURS[i % len(STATE_COLOURS)])
            if name in doc.on_bound:
                ax.annotate("on bound", (i, v), textcoords="offset points", xytext=(6, 4), fontsize=8)
        if bounds and name in bounds:
            for b in bounds[name]:
                ax.axhline(b, color="0.5", ls=":", lw=1)
        ax.set_yscale("log")
        ax.set_xticks(range(len(params)))
        ax.set_xticklabels([_label(s) for s in params])
        ax.set_xlim(-0.6, len(params) - 0.4)
        ax.set_title(name.replace("_N_per_m3", "") + " (N/m³)", fontsize=10)
        ax.grid(True, which="both", axis="y", alpha=0.3)
    fig.suptitle("Identified unit-area joint stiffness, 95 % intervals (dotted: DOE bounds)", fontsize=10)
    fig.tight_layout()
    return fig


def catalogue_rigidity(comparisons: dict[str, dict]):
    """A carriage's identified rigidity per state beside its guide catalogue's preload classes.

    Parameters
    ----------
    comparisons : {state: dict}
        The ``catalogue`` part of each state's ``carriage_rigidity.json``
        (:func:`jointid.response.carriage.catalogue_comparison`): per direction the identified value
        with its 95 % interval (markers, error bars) and each class's value (grey lines, labelled).
    """
    plt = _plt()
    first = next(iter(comparisons.values()))
    dirs = [d for d in ("normal", "lateral") if d in first["directions"]]
    fig, ax = plt.subplots(figsize=(7.2, 4.4))
    n = len(comparisons)
    for j, d in enumerate(dirs):
        classes = first["directions"][d]["classes"]
        values = [c["catalogue_N_per_um"] for c in classes.values()]
        ax.fill_between([j - 0.42, j + 0.42], min(values), max(values), color="0.88", zorder=0)
        for k, (name, c) in enumerate(sorted(classes.items(), key=lambda kv: kv[1]["catalogue_N_per_um"])):
            v = c["catalogue_N_per_um"]
            ax.hlines(v, j - 0.42, j + 0.42, color="0.45", lw=1.4, zorder=1)
            ax.annotate(f"{name} {v:,.0f}", (j - 0.42, v), textcoords="offset points", xytext=(-3, 4 * k - 4),
                        fontsize=7.5, color="0.3", ha="right", va="center")
        for i, (state, comp) in enumerate(comparisons.items()):
            doc = comp["directions"][d]
            v = doc["identified_N_per_um"]
            lo, hi = doc.get("identified_ci95_low_N_per_um", v), doc.get("identified_ci95_high_N_per_um", v)
            x = j + (i - (n - 1) / 2) * 0.18
            ax.errorbar([x], [v], yerr=[[max(v - lo, 0)], [max(hi - v, 0)]], fmt="o", ms=7, capsize=4, zorder=3,
                        color=STATE_COLOURS[i % len(STATE_COLOURS)], label=_label(state) if j == 0 else None)
    ax.set_xticks(range(len(dirs)))
    ax.set_xticklabels([f"{d} ({'Y' if d == 'normal' else 'X'})" for d in dirs])
    ax.set_xlim(-0.85, len(dirs) - 0.45)
    ax.set_ylim(0, None)
    ax.set_ylabel("rigidity of one carriage (N/µm)")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(title="identified (carriage on its rail,\n95 % interval)", fontsize=8, title_fontsize=8,
              loc="upper right")
    ax.set_title(f"Identified vs catalogue (grey: {first['block'].split(' (')[0]} preload classes)", fontsize=10)
    fig.tight_layout()
    return fig


def surface_diagnostics(diag: pd.DataFrame, limit_pct: float | None = None):
    """Response-surface quality per tracked mode: R², adjusted R², predicted R² and verification error."""
    plt = _plt()
    d = diag[diag["r2"].notna()].reset_index(drop=True)
    labels = [f"{int(m)}\n{f:.0f} Hz" for m, f in zip(d["tracked_mode"], d["ref_freq_Hz"])]
    x = np.arange(len(d))
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 3.8))
    for k, (col, name) in enumerate((("r2", "R²"), ("r2_adj", "adjusted R²"), ("r2_pred", "predicted R² (PRESS)"))):
        ax1.bar(x + (k - 1) * 0.27, d[col], 0.27, label=name)
    ax1.set_ylim(max(0.0, min(0.9, float(d[["r2", "r2_adj", "r2_pred"]].min().min()) - 0.02)), 1.002)
    ax1.set_xticks(x)
    ax1.set_xticklabels(labels, fontsize=8)
    ax1.set_xlabel("tracked mode")
    ax1.set_title("fit quality")
    ax1.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=3)
    ax1.grid(True, axis="y", alpha=0.3)
    ax2.bar(x, d["verify_max_error_pct"], 0.6, color="#8c564b")
    if limit_pct is not None:
        ax2.axhline(limit_pct, color="k", ls="--", lw=1,
                    label=f"surface.max_verification_error_pct = {limit_pct:g} %")
        ax2.legend(fontsize=8)
    ax2.set_xticks(x)
    ax2.set_xticklabels(labels, fontsize=8)
    ax2.set_xlabel("tracked mode")
    ax2.set_ylabel("max |surface − FE| at verification points (%)")
    ax2.set_title("verification at fresh FE solves")
    ax2.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    return fig


def doe_points(sheet: pd.DataFrame, identified: dict[str, list[float]]):
    """The DOE in coded coordinates (pairs of parameters) with the identified point of every state."""
    plt = _plt()
    cols = [c for c in sheet.columns if c.startswith("x_")]
    pairs = [(i, j) for i in range(len(cols)) for j in range(i + 1, len(cols))] or [(0, 0)]
    fig, axes = plt.subplots(1, len(pairs), figsize=(4.0 * len(pairs), 3.9), squeeze=False)
    for ax, (i, j) in zip(axes[0], pairs):
        for role, mk, c in (("design", "s", "0.35"), ("verify", "^", "#ff7f0e")):
            s = sheet[sheet["role"] == role]
            ax.scatter(s[cols[i]], s[cols[j]], marker=mk, color=c, s=36, label=f"{role} points")
        for k, (state, x) in enumerate(identified.items()):
            ax.scatter([x[i]], [x[j]], marker="*", s=180, color=STATE_COLOURS[k % len(STATE_COLOURS)],
                       edgecolor="k", label=f"identified, {_label(state)}", zorder=5)
        ax.set_xlim(-1.15, 1.15)
        ax.set_ylim(-1.15, 1.15)
        ax.set_xlabel(cols[i][2:].replace("_N_per_m3", "") + " (coded)")
        ax.set_ylabel(cols[j][2:].replace("_N_per_m3", "") + " (coded)")
        ax.set_aspect("equal")
        ax.grid(True, alpha=0.3)
    axes[0][0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.2), ncol=2)
    fig.suptitle("DOE in coded log-parameters (−1 = lower bound, +1 = upper bound)", fontsize=10)
    fig.tight_layout()
    return fig


def mode_shapes(points: pd.DataFrame, shapes: dict[str, list[dict]], ncol: int = 3):
    """Deformed measuring points (table grid and base lines) of the paired modes, ``ncol`` per row.

    Parameters
    ----------
    points : DataFrame
        ``measuring_points.csv`` (``point, part, x_m, y_m, z_m``).
    shapes : {state: [ {"title": str, "u": ndarray (n_points, 3)}, ... ]}
        Displacements of every point (any scale) for each mode to draw.
    ncol : int
        Pictures per row; each state starts a new row.
    """
    plt = _plt()
    rows_of = {s: max(1, -(-len(m) // ncol)) for s, m in shapes.items()}
    nrow = sum(rows_of.values())
    fig = plt.figure(figsize=(4.3 * ncol, 2.8 * nrow + 0.5))
    xyz = points[["x_m", "y_m", "z_m"]].to_numpy(float)
    span = float(np.ptp(xyz[:, 2]))
    lines = _grid_lines(points)
    row0 = 0
    for r, (state, modes) in enumerate(shapes.items()):
        colour = STATE_COLOURS[r % len(STATE_COLOURS)]
        for k, m in enumerate(modes):
            ax = fig.add_subplot(nrow, ncol, (row0 + k // ncol) * ncol + k % ncol + 1, projection="3d")
            u = np.asarray(m["u"], float)
            scale = 0.035 * span / max(np.abs(u).max(), 1e-300)
            d = xyz + scale * u
            amp = np.linalg.norm(u, axis=1)
            for idx in lines:
                ax.plot(xyz[idx, 2], xyz[idx, 0], xyz[idx, 1], color="0.75", lw=0.7)
                ax.plot(d[idx, 2], d[idx, 0], d[idx, 1], color=colour, lw=1.1)
            ax.scatter(d[:, 2], d[:, 0], d[:, 1], c=amp, cmap="viridis", s=12, depthshade=False)
            ax.set_title(f"{_label(state)} — {m['title']}", fontsize=9.5)
            ax.set_box_aspect((np.ptp(d[:, 2]) + 1e-9, np.ptp(d[:, 0]) + 1e-9, 2 * np.ptp(d[:, 1]) + 1e-9), zoom=1.45)
            ax.view_init(elev=22, azim=-60)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_zticks([])
            ax.set_xlabel("Z feed", fontsize=8, labelpad=-12)
            ax.set_ylabel("X", fontsize=8, labelpad=-12)
        row0 += rows_of[state]
    fig.suptitle("Paired mode shapes at the 36 measuring points — grey: undeformed; upper grid: table top, "
                 "lower lines: base top; colour: displacement amplitude", fontsize=11)
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.02, top=1 - 0.8 / (2.8 * nrow + 0.5), wspace=0.0,
                        hspace=0.12)
    return fig


def _grid_lines(points: pd.DataFrame) -> list[np.ndarray]:
    """Index arrays of polylines through the measuring points: along Z at each X, along X at each Z, per part."""
    out = []
    for _, grp in points.groupby("part", sort=False):
        for key, along in (("x_m", "z_m"), ("z_m", "x_m")):
            for _, line in grp.groupby(grp[key].round(6)):
                if len(line) > 1:
                    out.append(line.sort_values(along).index.to_numpy())
    return out
