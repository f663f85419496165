"""FRFs -> modes: the EMA of every state, its dataset folder and the engineer's tables.

:func:`extract_state` runs LSCF over orders, selects the physical poles, fits the shapes (LSFD) and
measures each mode's uncertainty (scatter over orders, bootstrap over rows).  :func:`dataset_tables`
turns the results into the tables of a dataset folder (modes.csv with ``damping_ratio`` and the
per-mode ``freq_uncertainty_pct``, ``damping_uncertainty_pct``, ``shape_uncertainty_pct``; shapes.csv;
frf.csv of the first reference; conditions.yaml), which :func:`jointid.data.dataset.write_dataset`
writes atomically.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from jointid.ema.frfs import FrfSet
from jointid.ema.options import EmaOptions
from jointid.ema.poles import PoleChart, Residues, lscf_chart, lsfd, pole_from
from jointid.ema.refine import Refined, guarded, refine_all
from jointid.ema.shapes import ModeShape, real_shape
from jointid.ema.stability import ChartPoint, Cluster, classify, select_physical
from jointid.ema.uncertainty import Bootstrap, bootstrap
from jointid.errors import DataError

__all__ = ["StateEma", "default_band", "extract_state", "misfit_ratios", "pole_table", "dataset_tables",
           "UNCERTAINTY_FLOOR_PCT", "MISFIT_RATIO"]

UNCERTAINTY_FLOOR_PCT = 1e-6
"""Smallest uncertainty written (percent): below it a noise-free fit's scatter is rounding."""
MISFIT_RATIO = 3.0
"""A pole whose local fit leaves residuals this many times those of its state's best-fitted pole has a
model error there (mostly a neighbour that LSCF did not resolve): its frequency and damping sigma are
scaled by that ratio and cover the distance to the LSCF estimate."""


@dataclass(frozen=True)
class StateEma:
    """The EMA of one state: its FRFs, chart, physical poles, residues, shapes and uncertainties."""

    frfs: FrfSet
    band_Hz: tuple
    chart: PoleChart
    points: list[ChartPoint]
    clusters: list[Cluster]
    refined: list[Refined]
    residues: Residues
    shapes: list[ModeShape]
    boot: Bootstrap | None
    freq_sigma_Hz: np.ndarray
    zeta_sigma: np.ndarray
    shape_sigma_pct: np.ndarray
    misfit: np.ndarray


def default_band(freq_Hz) -> tuple[float, float]:
    """The FRFs' band, 2 % of its width in from each end."""
    lo, hi = float(freq_Hz[0]), float(freq_Hz[-1])
    return lo + 0.02 * (hi - lo), hi - 0.02 * (hi - lo)


def extract_state(fs: FrfSet, options: EmaOptions, log=print, stream: int = 0) -> StateEma:
    """The EMA of the FRFs ``fs`` of one state; ``log`` gets the progress lines."""
    band = options.band_Hz or default_band(fs.freq_Hz)
    log(f"state {fs.state}: {fs.H.shape[0]} FRFs ({len(fs.references)} reference(s)), {fs.freq_Hz.size} lines, "
        f"band {band[0]:g}-{band[1]:g} Hz; LSCF at orders 2..{options.max_order}")
    chart = lscf_chart(fs.freq_Hz, fs.H, band, options.max_order, options.max_damping_ratio, fs.exp_decay_per_s)
    points = classify(chart, fs.freq_Hz, fs.H, options)
    clusters = select_physical(points, options)
    n_stable = sum(p.status == "stable" for p in points)
    if not clusters:
        raise DataError(f"{fs.source}: state {fs.state}: no stable pole in {band[0]:g}-{band[1]:g} Hz "
                        f"({len(points)} poles over {len(chart.orders)} orders, {n_stable} stable, none at "
                        f"{options.min_stable_orders} orders) — check that the band holds a resonance, raise "
                        "ema.max_order, or widen ema.band_Hz")
    log(f"state {fs.state}: {len(clusters)} physical poles from {n_stable} stable of {len(points)}: "
        + ", ".join(f"{c.freq_Hz:.1f} Hz" for c in clusters))
    f0, z0 = [c.freq_Hz for c in clusters], [c.zeta for c in clusters]
    refined = guarded(refine_all(fs.freq_Hz, fs.H, f0, z0, band), f0, z0, [c.freq_scatter_Hz for c in clusters],
                      [c.zeta_scatter for c in clusters], options.freq_tol_pct)
    for r in refined:
        if r.note != "refitted":
            log(f"state {fs.state}: {r.freq_Hz:.1f} Hz: {r.note}")
    f_ref = np.array([r.freq_Hz for r in refined])
    z_ref = np.array([r.zeta for r in refined])
    log(f"state {fs.state}: refined: " + ", ".join(f"{f:.2f} Hz" for f in f_ref))
    res = lsfd(fs.freq_Hz, fs.H, pole_from(f_ref, z_ref), band)
    shapes = [real_shape(fs.rows, res.A[:, m], res.sigma_A[:, m]) for m in range(len(clusters))]
    boot = None
    if options.n_bootstrap > 0:
        every = max(1, options.n_bootstrap // 4)
        tick = lambda b: (b + 1) % every == 0 and log(  # noqa: E731
            f"state {fs.state}: bootstrap over response rows {b + 1}/{options.n_bootstrap}")
        boot = bootstrap(fs, refined, shapes, band, options, stream=stream, progress=tick)
    fit_f = np.array([r.sigma_freq_Hz for r in refined])
    fit_z = np.array([r.sigma_zeta for r in refined])
    misfit = misfit_ratios(refined)
    sh_noise = np.array([np.sqrt(np.mean(s.sigma**2)) for s in shapes])
    b_f = fit_f * 0 if boot is None else np.nan_to_num(boot.freq_Hz)
    b_z = fit_z * 0 if boot is None else np.nan_to_num(boot.zeta)
    b_s = sh_noise * 0 if boot is None else np.nan_to_num(boot.shape)
    rms = np.array([np.sqrt(np.mean(s.value**2)) for s in shapes])
    sig_f, sig_z = np.fmax(fit_f, b_f), np.fmax(fit_z, b_z)
    bad = (misfit > MISFIT_RATIO) & np.array([r.note == "refitted" for r in refined])  # a kept LSCF pole has its sigma
    sig_f = np.where(bad, np.fmax(sig_f * misfit, np.abs(f_ref - f0)), sig_f)
    sig_z = np.where(bad, np.fmax(sig_z * misfit, np.abs(z_ref - z0)), sig_z)
    for m in np.flatnonzero(bad):
        log(f"state {fs.state}: {f_ref[m]:.1f} Hz fits {misfit[m]:.1f} times worse than the state's best mode "
            "(an unresolved neighbour?): its sigma is scaled by that and covers the LSCF estimate")
    return StateEma(fs, tuple(band), chart, points, clusters, refined, res, shapes, boot, sig_f, sig_z,
                    100 * np.hypot(sh_noise, b_s) / rms, misfit)


def misfit_ratios(refined) -> np.ndarray:
    """Each pole's local-fit residual rms over the smallest of its state (1: fits as well as the best)."""
    rms = np.array([r.residual_rms for r in refined])
    best = np.nanmin(rms) if np.any(np.isfinite(rms)) else np.nan
    return np.where(np.isfinite(rms) & (best > 0), rms / best, 1.0)


def _pct(sigma, value) -> np.ndarray:
    return np.maximum(100 * np.asarray(sigma) / np.asarray(value), UNCERTAINTY_FLOOR_PCT)


def pole_table(result: StateEma) -> pd.DataFrame:
    """One row per physical pole: f, zeta, their uncertainties and parts, the stable orders, MPC."""
    fs = result.frfs
    sel = (fs.freq_Hz >= result.band_Hz[0]) & (fs.freq_Hz <= result.band_Hz[1])
    rows = []
    for m, (c, r, sh) in enumerate(zip(result.clusters, result.refined, result.shapes)):
        boot = result.boot
        rows.append({
            "state": fs.state, "mode": m + 1, "freq_Hz": r.freq_Hz, "damping_ratio": r.zeta,
            "freq_uncertainty_pct": _pct(result.freq_sigma_Hz[m], r.freq_Hz),
            "damping_uncertainty_pct": _pct(result.zeta_sigma[m], r.zeta),
            "shape_uncertainty_pct": max(float(result.shape_sigma_pct[m]), UNCERTAINTY_FLOOR_PCT),
            "freq_fit_sigma_Hz": r.sigma_freq_Hz,
            "freq_bootstrap_sigma_Hz": np.nan if boot is None else boot.freq_Hz[m],
            "damping_fit_sigma": r.sigma_zeta,
            "damping_bootstrap_sigma": np.nan if boot is None else boot.zeta[m],
            "bootstrap_kept": "" if boot is None else f"{int(boot.found[m])}/{boot.n}",
            "freq_lscf_Hz": c.freq_Hz, "freq_scatter_orders_Hz": c.freq_scatter_Hz,
            "damping_lscf": c.zeta, "damping_scatter_orders": c.zeta_scatter,
            "n_stable_orders": len(c.members), "orders": f"{c.orders[0]}-{c.orders[-1]}",
            "n_lines_fit": r.n_lines, "fit_residual_rms": r.residual_rms, "misfit_ratio": result.misfit[m],
            "refit": r.note, "mpc": sh.mpc, "real_share": sh.real_share,
        })
    table = pd.DataFrame(rows)
    err = np.linalg.norm(result.residues.synth[:, sel] - fs.H[:, sel]) / np.linalg.norm(fs.H[:, sel])
    table["synth_error_pct"] = 100 * err
    return table


def dataset_tables(results: list[StateEma], conditions: dict, source: str) -> dict:
    """``modes``, ``shapes``, ``frf`` tables and ``conditions`` of the dataset folder of ``results``."""
    modes = pd.concat([pole_table(r) for r in results], ignore_index=True)
    modes = modes[["state", "mode", "freq_Hz", "damping_ratio", "freq_uncertainty_pct", "damping_uncertainty_pct",
                   "shape_uncertainty_pct"]]
    shape_rows, frf_rows, states = [], [], {}
    old = conditions.get("states") or {}
    for r in results:
        fs = r.frfs
        for m, sh in enumerate(r.shapes):
            shape_rows += [{"state": fs.state, "mode": m + 1, "point": p, "direction": d, "value": float(v)}
                           for (p, d), v in zip(sh.dofs, sh.value)]
        ref = fs.rows[["ref_point", "ref_direction"]].iloc[0]
        first = np.flatnonzero((fs.rows["ref_point"] == ref.iloc[0]) & (fs.rows["ref_direction"] == ref.iloc[1]))
        for i in first:
            row = fs.rows.iloc[i]
            frf_rows += [{"state": fs.state, "point": row["point"], "direction": row["direction"], "freq_Hz": float(f),
                          "re": float(h.real), "im": float(h.imag)} for f, h in zip(fs.freq_Hz, fs.H[i])]
        keep = {k: v for k, v in (old.get(fs.state) or {}).items() if k in ("em_force_N", "currents", "motor_position_m",
                                                                            "notes")}
        states[fs.state] = {"em_force_N": 0.0, **keep, "frf_drive_point": str(ref.iloc[0]),
                            "frf_drive_direction": str(ref.iloc[1])}
    cond = {"source": f"EMA (jointid.ema: LSCF, LSFD; sdypy-EMA) of {source}"
                      + (f"; {conditions['source']}" if conditions.get("source") else ""),
            "frequencies_in_Hz_confirmed": True,
            "notes": "per-mode uncertainties measured by the EMA (modes.csv); no global noise stated",
            "states": states}
    for key in ("test_setup", "computed_on_mesh"):  # a synthetic source's mesh digest passes through
        if key in conditions:
            cond[key] = conditions[key]
    return {"modes": modes, "shapes": pd.DataFrame(shape_rows) if shape_rows else None,
            "frf": pd.DataFrame(frf_rows) if frf_rows else None, "conditions": cond}
