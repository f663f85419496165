"""Each physical pole's uncertainty: the scatter over model orders and a bootstrap over response rows.

A bootstrap replicate draws the FRF rows with replacement (seeded), runs LSCF again and takes, at each
order where the pole was stable, the closest pole within ``freq_tol_pct``; the medians over those orders
are the replicate's frequency and damping.  Its shapes are the LSFD of all rows at the replicate's
poles.  The standard deviations over replicates are the bootstrap's part; the scatter over orders is
added in quadrature.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jointid.ema.frfs import FrfSet
from jointid.ema.options import EmaOptions
from jointid.ema.poles import lscf_chart, lsfd, pole_freq_damping, pole_from
from jointid.ema.shapes import real_shape
from jointid.ema.stability import Cluster

__all__ = ["Bootstrap", "bootstrap"]


@dataclass(frozen=True)
class Bootstrap:
    """Per physical pole: 1-sigma over the replicates of frequency (Hz), damping ratio and shape
    (rms over DOFs, same scale as the shape), and how many replicates found the pole."""

    freq_Hz: np.ndarray
    zeta: np.ndarray
    shape: np.ndarray
    found: np.ndarray
    n: int


def _align(ref: np.ndarray, other: np.ndarray) -> np.ndarray:
    """``other`` scaled (least squares, sign included) onto ``ref``."""
    den = other @ other
    return other * (ref @ other / den) if den > 0 else other


def bootstrap(fs: FrfSet, clusters: list[Cluster], shapes, band_Hz, options: EmaOptions,
              stream: int = 0, progress=None) -> Bootstrap:
    # many parameters: the state's FRFs, its poles and shapes, the band, the options, the seed stream, progress
    """Bootstrap over the response rows of ``fs`` for the physical poles ``clusters`` (their nominal
    real ``shapes``); ``stream`` separates the seeds of the states."""
    n_modes, n = len(clusters), int(options.n_bootstrap)
    f_b = np.full((n, n_modes), np.nan)
    z_b = np.full((n, n_modes), np.nan)
    sh_b = np.full((n, n_modes, len(shapes[0].value) if shapes else 0), np.nan)
    rng = np.random.default_rng([int(options.seed), int(stream)])
    n_rows = fs.H.shape[0]
    for b in range(n):
        idx = rng.integers(0, n_rows, n_rows)
        chart = lscf_chart(fs.freq_Hz, fs.H[idx], band_Hz, options.max_order, options.max_damping_ratio,
                           fs.exp_decay_per_s)
        by_order = dict(zip(chart.orders.tolist(), chart.poles))
        for m, cl in enumerate(clusters):
            fs_m, zs_m = [], []
            for order in cl.orders:
                p = by_order.get(order, np.empty(0))
                if p.size == 0:
                    continue
                f, z = pole_freq_damping(p)
                k = int(np.argmin(np.abs(f - cl.freq_Hz)))
                if abs(f[k] - cl.freq_Hz) <= options.freq_tol_pct / 100 * cl.freq_Hz:
                    fs_m.append(f[k])
                    zs_m.append(z[k])
            if fs_m:
                f_b[b, m], z_b[b, m] = np.median(fs_m), np.median(zs_m)
        f_use = np.where(np.isnan(f_b[b]), [c.freq_Hz for c in clusters], f_b[b])
        z_use = np.where(np.isnan(z_b[b]), [c.zeta for c in clusters], z_b[b])
        res = lsfd(fs.freq_Hz, fs.H, pole_from(f_use, z_use), band_Hz)
        for m in range(n_modes):
            if not np.isnan(f_b[b, m]):
                sh = real_shape(fs.rows, res.A[:, m], res.sigma_A[:, m])
                if len(sh.value) == sh_b.shape[2]:
                    sh_b[b, m] = _align(shapes[m].value, sh.value)
        if progress is not None:
            progress(b)
    found = np.sum(~np.isnan(f_b), axis=0)
    ok = found >= 2
    sd = lambda x: np.where(ok, np.nanstd(x, axis=0, ddof=1) if n > 1 else 0.0, np.nan)  # noqa: E731
    shape_sd = np.sqrt(np.nanmean(np.nanvar(sh_b, axis=0, ddof=1), axis=1)) if n > 1 and sh_b.size else np.zeros(n_modes)
    return Bootstrap(sd(f_b), sd(z_b), np.where(ok, shape_sd, np.nan), found, n)
