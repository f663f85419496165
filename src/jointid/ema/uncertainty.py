"""Each mode's bootstrap over response rows: how much its refined pole and shape move when the FRF rows
are drawn again with replacement (seeded).

A replicate refits every pole on the drawn rows by one Gauss-Newton step from the refined pole: the
local fit's residuals separate by FRF row, so the step is ``-(sum_i c_i J_i^T J_i)^-1 sum_i c_i J_i^T r_i``
with ``c_i`` the times row i was drawn (:class:`jointid.ema.refine.Refined` keeps the blocks).  Its
shapes are the LSFD of all rows at the replicate's poles.  A replicate that moves a pole by more than
``freq_tol_pct`` does not count for that pole.  The standard deviations over the
replicates are the bootstrap's 1-sigma.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from jointid.ema.frfs import FrfSet
from jointid.ema.options import EmaOptions
from jointid.ema.poles import lsfd, pole_from
from jointid.ema.refine import Refined
from jointid.ema.shapes import real_shape
from jointid.ema.stability import QUICK_LINES

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


def bootstrap(fs: FrfSet, refined: list[Refined], shapes, band_Hz, options: EmaOptions, stream: int = 0,
              progress=None) -> Bootstrap:
    # many parameters: the state's FRFs, its refined poles and shapes, the band, the options, seed stream, progress
    """Bootstrap over the response rows of ``fs`` of the ``refined`` poles and their nominal real
    ``shapes``; ``stream`` separates the seeds of the states."""
    n_modes, n = len(refined), int(options.n_bootstrap)
    x0 = np.array([[r.freq_Hz, r.zeta] for r in refined])
    f_b = np.full((n, n_modes), np.nan)
    z_b = np.full((n, n_modes), np.nan)
    n_dof = len(shapes[0].value) if shapes else 0
    sh_b = np.full((n, n_modes, n_dof), np.nan)
    rng = np.random.default_rng([int(options.seed), int(stream)])
    n_rows = fs.H.shape[0]
    for b in range(n):
        counts = np.bincount(rng.integers(0, n_rows, n_rows), minlength=n_rows).astype(float)
        for m, r in enumerate(refined):
            if r.row_jtj is None:  # an LSCF pole kept in place of its refit: no local fit to step
                continue
            jtj = np.einsum("r,rij->ij", counts, r.row_jtj)
            jtr = counts @ r.row_jtr
            try:
                step = np.linalg.solve(jtj, jtr)
            except np.linalg.LinAlgError:
                continue
            f, z = x0[m] - step
            if abs(f - x0[m, 0]) <= options.freq_tol_pct / 100 * x0[m, 0] and 0 < z < options.max_damping_ratio:
                f_b[b, m], z_b[b, m] = f, z
        ok = ~np.isnan(f_b[b])
        res = lsfd(fs.freq_Hz, fs.H, pole_from(np.where(ok, f_b[b], x0[:, 0]), np.where(ok, z_b[b], x0[:, 1])),
                   band_Hz, max_lines=QUICK_LINES)
        for m in np.flatnonzero(ok):
            sh = real_shape(fs.rows, res.A[:, m], res.sigma_A[:, m])
            if len(sh.value) == n_dof:
                sh_b[b, m] = _align(shapes[m].value, sh.value)
        if progress is not None:
            progress(b)
    found = np.sum(~np.isnan(f_b), axis=0)
    good = found >= 2
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sd_f = np.where(good, np.nanstd(f_b, axis=0, ddof=1), np.nan) if n > 1 else np.full(n_modes, np.nan)
        sd_z = np.where(good, np.nanstd(z_b, axis=0, ddof=1), np.nan) if n > 1 else np.full(n_modes, np.nan)
        sd_s = (np.sqrt(np.nanmean(np.nanvar(sh_b, axis=0, ddof=1), axis=1)) if n > 1 and n_dof
                else np.full(n_modes, np.nan))
    return Bootstrap(sd_f, sd_z, np.where(good, sd_s, np.nan), found, n)
