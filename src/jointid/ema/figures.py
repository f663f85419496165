"""What the engineer looks at: the stabilisation chart and the synthesised against the measured FRFs.

Matplotlib with the Agg backend, imported inside each function; PNGs are written atomically.
"""

from __future__ import annotations

import numpy as np

from jointid.io import atomic_path

__all__ = ["stabilisation_chart", "frf_overlay", "cross_row"]

_STYLE = {"new": ("o", "#bbbbbb", "new"), "freq": ("x", "#7aa6c2", "stable f"),
          "damp": ("+", "#2b6f9e", "stable f, ζ"), "stable": ("^", "#c0392b", "stable f, ζ, shape")}


def _plt():
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt  # noqa: PLC0415

    return plt


def stabilisation_chart(result, path) -> None:
    """The poles of every order (marker by stability), the selected poles as vertical lines, and the
    sum of the FRF magnitudes behind them; one state (:class:`jointid.ema.extract.StateEma`)."""
    plt = _plt()
    fs = result.frfs
    fig, ax = plt.subplots(figsize=(9, 5.5))
    for status, (marker, colour, label) in _STYLE.items():
        pts = [p for p in result.points if p.status == status]
        if pts:
            ax.plot([p.freq_Hz for p in pts], [p.order for p in pts], marker, ms=4, color=colour, ls="none",
                    label=label, mfc="none" if marker == "o" else colour)
    for r in result.refined:
        ax.axvline(r.freq_Hz, color="#27ae60", lw=1.0, alpha=0.8)
    ax.plot([], [], color="#27ae60", label="selected (refined)")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("model order")
    ax.set_xlim(*result.band_Hz)
    ax2 = ax.twinx()
    sel = (fs.freq_Hz >= result.band_Hz[0]) & (fs.freq_Hz <= result.band_Hz[1])
    ax2.semilogy(fs.freq_Hz[sel], np.sum(np.abs(fs.H[:, sel]), axis=0), color="#444444", lw=0.8)
    ax2.set_ylabel("sum of |H| (m/N)")
    ax.set_title(f"stabilisation chart, state {fs.state}: {len(result.refined)} physical poles")
    ax.legend(loc="upper left", fontsize=8, framealpha=0.9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def cross_row(fs) -> int:
    """The cross point shown beside the drive point: the non-driving row with the largest FRF."""
    drive = set(fs.drive_rows())
    norms = np.linalg.norm(fs.H, axis=1)
    order = [i for i in np.argsort(-norms) if i not in drive]
    return int(order[0]) if order else 0


def frf_overlay(result, path) -> None:
    """Measured against synthesised receptance (magnitude and phase) at the drive point and one cross
    point of one state."""
    plt = _plt()
    fs = result.frfs
    rows = list(dict.fromkeys((fs.drive_rows()[:1] or [0]) + [cross_row(fs)]))
    sel = (fs.freq_Hz >= result.band_Hz[0]) & (fs.freq_Hz <= result.band_Hz[1])
    fig, axes = plt.subplots(2, len(rows), figsize=(5 * len(rows), 6), sharex=True, squeeze=False)
    for k, i in enumerate(rows):
        r = fs.rows.iloc[i]
        title = f"{r['point']}:{r['direction']} / {r['ref_point']}:{r['ref_direction']}"
        title = ("drive point " if i in fs.drive_rows() else "cross point ") + title
        f, h, s = fs.freq_Hz[sel], fs.H[i, sel], result.residues.synth[i, sel]
        axes[0, k].semilogy(f, np.abs(h), color="#444444", lw=0.9, label="measured")
        axes[0, k].semilogy(f, np.abs(s), color="#c0392b", lw=1.0, ls="--", label="synthesised (LSFD)")
        axes[1, k].plot(f, np.degrees(np.angle(h)), color="#444444", lw=0.9)
        axes[1, k].plot(f, np.degrees(np.angle(s)), color="#c0392b", lw=1.0, ls="--")
        axes[0, k].set_title(title, fontsize=9)
        axes[0, k].set_ylabel("|H| (m/N)")
        axes[1, k].set_ylabel("phase (deg)")
        axes[1, k].set_xlabel("frequency (Hz)")
        for rr in result.refined:
            axes[0, k].axvline(rr.freq_Hz, color="#27ae60", lw=0.6, alpha=0.6)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(f"state {fs.state}: measured and synthesised FRFs")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
