"""The governing mode of the dynamic stiffness, and its range over drive points and damping laws.

Table 1 of the paper is one number per state: the minimum over the band of the drive-point dynamic
stiffness ``|F/X|``.  That minimum sits at a resonance, ``K_min ~ 2 zeta_r k_r`` with the modal
stiffness ``k_r = w_r^2 / (p^T phi_r)^2`` at the drive point, so it inherits three choices the paper
does not publish: which mode governs (is it one the test saw?), the drive point, and the damping.

* :func:`band_minimum` - the minimum of ``|F/X|`` over the band, the mode that dominates the
  receptance there, and the *paired* minimum: the lowest resonance peak of a mode that is paired with
  a measured one (the only modes the test validates).
* Damping laws (:data:`LAWS`, :func:`law_damping`, :func:`calibrate`):

  ``modal``             constant modal ratio, ``zeta_r = zeta``;
  ``joint_dashpot``     dashpots in the joints ``c = eta k_joint`` (eta in s):
                        ``zeta_r = eta w_r e_r / 2``;
  ``joint_hysteretic``  a constant joint loss factor, ``k_joint (1 + i gamma)``: modal loss factor
                        ``gamma e_r``, i.e. ``zeta_r ~ gamma e_r / 2`` at resonance, frequency independent;

  with ``e_r`` the share of mode r's strain energy in the joint springs.  Between two joint states
  ``K_min = 2 zeta_r k_r`` scales as ``k_r`` (modal), ``k_r w_r e_r`` (dashpot) and ``k_r e_r``
  (hysteretic); only if ``e_r ~ 1`` and the mode's mass is unchanged is the dashpot law's ratio
  ``(f_on/f_off)^3``.
* :func:`case_table` - every (drive point, damping law) case of one state; :func:`range_table` -
  the min-max of ``K_min`` and of the increase between states over the cases.
* :func:`damping_ratio_range` - ``K_min`` at the drive point over a stated range of the modal damping
  ratio (a nuisance parameter: the paper publishes no damping), under one or several pairings.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from jointid.errors import ConfigError
from jointid.response import harmonic as hm

__all__ = ["LAWS", "band_minimum", "calibrate", "case_table", "damping_ratio_range", "damping_vectors_range",
           "law_damping", "modal_frf", "range_table"]

LAWS = ("modal", "joint_dashpot", "joint_hysteretic")
"""The damping laws of the ranges (module docstring)."""
LAW_TEXT = {"modal": "constant modal ζ", "joint_dashpot": "joint dashpots c = η·k_joint",
            "joint_hysteretic": "joint loss factor k_joint(1 + iγ)"}


def law_damping(law: str, freqs_Hz, share, param: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-mode viscous ratio ``zeta`` and hysteretic modal loss factor ``g`` of a damping law.

    ``param`` is ``zeta`` (modal), ``eta`` in s (joint_dashpot) or ``gamma`` (joint_hysteretic);
    ``share`` the joint strain-energy share ``e_r`` of each mode.  Rigid-body modes get 0.
    """
    f = np.asarray(freqs_Hz, dtype=float)
    e = np.clip(np.asarray(share, dtype=float), 0.0, 1.0)
    zeta, g = np.zeros(f.size), np.zeros(f.size)
    elastic = f >= hm.RIGID_HZ
    if law == "modal":
        zeta[elastic] = param
    elif law == "joint_dashpot":
        zeta[elastic] = param * 2 * np.pi * f[elastic] * e[elastic] / 2
    elif law == "joint_hysteretic":
        g[elastic] = param * e[elastic]
    else:
        raise ConfigError(f"damping law {law!r} is unknown; use one of {', '.join(LAWS)}")
    return zeta, g


def calibrate(law: str, zeta_target: float, f_Hz: float, share: float) -> float:
    """The parameter of ``law`` that gives a mode at ``f_Hz`` with joint share ``share`` the ratio
    ``zeta_target`` (for the hysteretic law, the equivalent ratio ``g / 2`` at resonance)."""
    if law == "modal":
        return float(zeta_target)
    if not share > 0:
        raise ConfigError(f"cannot calibrate damping law {law!r} on a mode with no strain energy in the joints")
    if law == "joint_dashpot":
        return 2 * float(zeta_target) / (2 * np.pi * float(f_Hz) * float(share))
    if law == "joint_hysteretic":
        return 2 * float(zeta_target) / float(share)
    raise ConfigError(f"damping law {law!r} is unknown; use one of {', '.join(LAWS)}")


def _terms(f_Hz, freqs_Hz, zeta, g, pphi) -> np.ndarray:
    """Modal terms ``pphi_r^2 / (w_r^2 - w^2 + 2 i zeta_r w_r w + i g_r w_r^2)``, shape (n_f, n_modes)."""
    w = 2 * np.pi * np.asarray(f_Hz, dtype=float)[:, None]
    wr = 2 * np.pi * np.asarray(freqs_Hz, dtype=float)[None, :]
    den = wr**2 - w**2 + 2j * np.asarray(zeta)[None, :] * wr * w + 1j * np.asarray(g)[None, :] * wr**2
    return np.asarray(pphi, dtype=float)[None, :] ** 2 / den


def modal_frf(f_Hz, freqs_Hz, zeta, g, pphi, residual: float = 0.0) -> np.ndarray:
    """Drive-point receptance (m/N) with viscous ratios ``zeta`` and hysteretic loss factors ``g``."""
    return _terms(f_Hz, freqs_Hz, zeta, g, pphi).sum(axis=1) + float(residual)


def band_minimum(band_Hz, freqs_Hz, zeta, g, pphi, residual: float = 0.0, *, paired=None,
                 n_freq: int = 1601, f_Hz=None, H=None) -> dict:
    # many parameters: the drive point's modal data (one array each) and the band's options
    """Minimum of ``|F/X|`` over the band, the mode that sets it, and the lowest paired resonance peak.

    Parameters
    ----------
    band_Hz : (float, float)
    freqs_Hz, zeta, g, pphi : array_like, shape (n_modes,)
        Natural frequencies (Hz), viscous ratios, hysteretic modal loss factors and drive-point
        participations ``p^T phi_r``.
    residual : float
        Static residual flexibility (m/N).
    paired : array_like of bool, shape (n_modes,), optional
        The modes paired with a measured mode; None = none.
    n_freq : int
        Lines of the base grid (points around every resonance are added).
    f_Hz, H : array_like, optional
        A grid and its receptance to use instead (e.g. the harmonic stage's), consistent with the modes.

    Returns
    -------
    dict
        ``k_min_N_per_m, f_at_min_Hz, mode`` (0-based, the mode with the largest term there) and
        ``k_paired_N_per_m, f_paired_Hz, mode_paired``: the lowest resonance peak of a paired mode, i.e.
        over the paired modes r in the band, the local minimum of ``|F/X|`` strictly inside the
        half-power band ``f_r (1 +- zeta_eq)`` (``zeta_eq = zeta + g / 2``) where no mode with a larger
        resonance amplitude ``pphi^2 / (2 zeta_eq w^2)`` resonates too (None when no paired mode shows
        a peak of its own: its valley is swamped by a neighbour's flank).
    """
    fr = np.asarray(freqs_Hz, dtype=float)
    z, gg = np.asarray(zeta, dtype=float), np.asarray(g, dtype=float)
    zeq = z + gg / 2
    lo, hi = float(band_Hz[0]), float(band_Hz[1])
    if f_Hz is None:
        f_Hz = np.unique(np.concatenate([np.linspace(lo, hi, int(n_freq)), hm.resonance_grid(lo, hi, fr, zeq)]))
    f = np.asarray(f_Hz, dtype=float)
    terms = _terms(f, fr, z, gg, pphi)
    if H is None:
        H = terms.sum(axis=1) + float(residual)
    kd = 1.0 / np.abs(np.asarray(H))
    dominant = np.argmax(np.abs(terms), axis=1)
    i = int(np.argmin(kd))
    out = {"k_min_N_per_m": float(kd[i]), "f_at_min_Hz": float(f[i]), "mode": int(dominant[i]),
           "k_paired_N_per_m": None, "f_paired_Hz": None, "mode_paired": None}
    best = np.inf
    with np.errstate(divide="ignore"):
        peak = np.where(zeq > 0, np.asarray(pphi, float) ** 2 / (2 * zeq * (2 * np.pi * fr) ** 2), np.inf)
    for r in np.flatnonzero(np.zeros(fr.size, bool) if paired is None else np.asarray(paired, bool)):
        if not (lo <= fr[r] <= hi and zeq[r] > 0):
            continue
        band_r = (fr[r] * (1 - zeq[r]), fr[r] * (1 + zeq[r]))
        win = np.flatnonzero((f >= band_r[0]) & (f <= band_r[1]))
        if win.size < 3:
            continue
        j = int(win[np.argmin(kd[win])])
        # a peak of its own: a local minimum inside the half-power band, and no stronger mode resonating there
        rivals = (fr >= band_r[0]) & (fr <= band_r[1]) & (peak > peak[r])
        if win[0] < j < win[-1] and not rivals.any() and kd[j] < best:
            best = kd[j]
            out.update(k_paired_N_per_m=float(kd[j]), f_paired_Hz=float(f[j]), mode_paired=int(r))
    return out


def case_table(data: dict, laws: dict[str, float], *, band_Hz, n_freq: int = 1601) -> pd.DataFrame:
    """``K_min`` of one state for every drive point and damping law.

    Parameters
    ----------
    data : dict
        The harmonic stage's ``drive_points.npz``: ``points (n_pts,)``, ``pphi (n_pts, n_modes)``,
        ``residual_m_per_N (n_pts,)``, ``freqs_Hz, joint_share, measured_order (n_modes,)`` (0 =
        no measured partner).
    laws : dict
        Law name -> its parameter (:func:`law_damping`), e.g. from :func:`calibrate`.
    band_Hz, n_freq
        As :func:`band_minimum`.

    Returns
    -------
    DataFrame
        One row per (point, law): ``point, damping_law, law_parameter, k_min_N_per_mm, f_at_min_Hz,
        fe_mode, measured_order, k_paired_N_per_mm, f_paired_Hz, paired_fe_mode, paired_measured_order``
        (FE modes 1-based, empty where there is none).
    """
    fr = np.asarray(data["freqs_Hz"], dtype=float)
    order = np.asarray(data["measured_order"], dtype=int)
    rows = []
    for law, param in laws.items():
        zeta, g = law_damping(law, fr, data["joint_share"], param)
        for k, point in enumerate(np.asarray(data["points"]).astype(str)):
            m = band_minimum(band_Hz, fr, zeta, g, data["pphi"][k], float(data["residual_m_per_N"][k]),
                             paired=order > 0, n_freq=n_freq)
            rp = m["mode_paired"]
            rows.append({"point": point, "damping_law": law, "law_parameter": float(param),
                         "k_min_N_per_mm": m["k_min_N_per_m"] * 1e-3, "f_at_min_Hz": m["f_at_min_Hz"],
                         "fe_mode": m["mode"] + 1, "measured_order": int(order[m["mode"]]) or None,
                         "k_paired_N_per_mm": None if rp is None else m["k_paired_N_per_m"] * 1e-3,
                         "f_paired_Hz": m["f_paired_Hz"], "paired_fe_mode": None if rp is None else rp + 1,
                         "paired_measured_order": None if rp is None else int(order[rp])})
    df = pd.DataFrame(rows)
    for c in ("measured_order", "paired_fe_mode", "paired_measured_order"):
        df[c] = df[c].astype("Int64")
    df["k_paired_N_per_mm"] = df["k_paired_N_per_mm"].astype(float)
    return df


def range_table(cases: dict[str, pd.DataFrame], reference: str, drive_point: str,
                paper_increase_pct: dict[str, float] | None = None) -> pd.DataFrame:
    """Min-max of ``K_min`` and of the increase vs ``reference`` over drive points and damping laws.

    ``cases`` maps each state to its :func:`case_table`.  For each other state, each basis (``paired``:
    the lowest resonance peak of a paired mode; ``all``: the band minimum over all modes) and each
    set of cases (the points under each law; the laws at ``drive_point``; all points under all laws)
    one row: ``state, reference_state, basis, over, n_cases``, the lowest and highest ``K_min`` of
    the reference (``reference_k_min_low/high_N_per_mm``) and of the state (``k_min_low/high_N_per_mm``),
    ``increase_low_pct, increase_high_pct`` (taken case by case: same point and law in both states),
    ``paper_increase_pct`` and ``paper_inside`` (the paper's increase within the range).
    """
    ref = cases[reference].set_index(["point", "damping_law"])
    laws = list(dict.fromkeys(cases[reference]["damping_law"]))
    rows = []
    for state, df in cases.items():
        if state == reference:
            continue
        cur = df.set_index(["point", "damping_law"]).reindex(ref.index)
        paper = (paper_increase_pct or {}).get(state, np.nan)
        for basis, col in (("paired modes", "k_paired_N_per_mm"), ("all modes", "k_min_N_per_mm")):
            pts, law = ref.index.get_level_values(0), ref.index.get_level_values(1)
            sets = [(f"points, {LAW_TEXT[lw]}", law == lw) for lw in laws]
            sets += [(f"damping laws at {drive_point}", pts == drive_point), ("points × damping laws", pts == pts)]
            for over, sel in sets:
                a, b = ref.loc[sel, col].to_numpy(float), cur.loc[sel, col].to_numpy(float)
                ok = np.isfinite(a) & np.isfinite(b)
                inc = 100 * (b[ok] / a[ok] - 1)
                rng = lambda v: (float(np.min(v)), float(np.max(v))) if v.size else (np.nan, np.nan)  # noqa: E731
                (a0, a1), (b0, b1), (i0, i1) = rng(a[ok]), rng(b[ok]), rng(inc)
                rows.append({"state": state, "reference_state": reference, "basis": basis, "over": over,
                             "n_cases": int(ok.sum()), "reference_k_min_low_N_per_mm": a0,
                             "reference_k_min_high_N_per_mm": a1, "k_min_low_N_per_mm": b0,
                             "k_min_high_N_per_mm": b1, "increase_low_pct": i0, "increase_high_pct": i1,
                             "paper_increase_pct": paper,
                             "paper_inside": bool(ok.any() and i0 <= paper <= i1)})
    return pd.DataFrame(rows)


def damping_ratio_range(band_Hz, freqs_Hz, zeta, pphi, residual: float, ratio_range, *, fixed=None,
                        paired: dict | None = None, n_grid: int = 7, n_freq: int = 1601) -> dict:
    # many parameters: the drive point's modal data (one array each) and the range's options
    """``K_min`` of the drive point over a range of the modal damping ratio.

    Every elastic mode not in ``fixed`` (e.g. the modes with a measured ratio, which keep ``zeta``)
    gets the same ratio, on ``n_grid`` ratios evenly spaced over ``ratio_range = [low, high]`` (both
    ends included: ``K_min ~ 2 zeta_r k_r`` is close to linear in the ratio, but a neighbour's flank
    can bend it, so the extremes are taken over the grid, not assumed at the ends).

    Parameters
    ----------
    band_Hz, freqs_Hz, zeta, pphi, residual
        As :func:`band_minimum` (``zeta``: the ratios of the configured damping model).
    ratio_range : (float, float)
        Lowest and highest damping ratio, 0 < low <= high < 1.
    fixed : array_like of bool, optional
        Modes whose ratio is kept.
    paired : dict, optional
        Pairing name -> bool per mode (paired with a measured mode): the lowest paired peak under each.

    Returns
    -------
    dict
        ``damping_ratio_low, damping_ratio_high, damping_ratio_grid``; ``k_min_N_per_m`` and
        ``governing_fe_mode`` (1-based) per grid ratio, ``k_min_low_N_per_m, k_min_high_N_per_m``;
        ``paired``: per pairing name ``k_paired_N_per_m`` and ``paired_fe_mode`` per grid ratio (None
        where no paired mode shows a peak of its own) and their ``k_paired_low/high_N_per_m``.
    """
    lo, hi = (float(v) for v in ratio_range)
    if not 0 < lo <= hi < 1:
        raise ConfigError(f"harmonic.damping.damping_ratio_range = {list(ratio_range)}: give [low, high] with "
                          "0 < low <= high < 1")
    fr = np.asarray(freqs_Hz, dtype=float)
    keep = np.zeros(fr.size, bool) if fixed is None else np.asarray(fixed, bool)
    vary = (fr >= hm.RIGID_HZ) & ~keep
    grid = np.linspace(lo, hi, int(n_grid)) if hi > lo else np.array([lo])
    out = {"damping_ratio_low": lo, "damping_ratio_high": hi, "damping_ratio_grid": grid.tolist()}
    zetas = [np.where(vary, z, np.asarray(zeta, dtype=float)) for z in grid]
    return out | damping_vectors_range(band_Hz, fr, zetas, pphi, residual, paired=paired, n_freq=n_freq)


def damping_vectors_range(band_Hz, freqs_Hz, zetas, pphi, residual: float, *, paired: dict | None = None,
                          n_freq: int = 1601) -> dict:
    """``K_min`` of the drive point under each of several damping-ratio vectors ``zetas`` (a list of
    ``(n_modes,)`` arrays: the grid of :func:`damping_ratio_range`, or an identified law at its interval
    ends); the other arguments and the keys ``k_min_N_per_m`` ... ``paired`` as there."""
    fr = np.asarray(freqs_Hz, dtype=float)
    paired = paired or {}
    out = {"k_min_N_per_m": [], "governing_fe_mode": [],
           "paired": {name: {"k_paired_N_per_m": [], "paired_fe_mode": []} for name in paired}}
    for zz in zetas:
        m = band_minimum(band_Hz, fr, zz, np.zeros(fr.size), pphi, residual, n_freq=n_freq)
        out["k_min_N_per_m"].append(m["k_min_N_per_m"])
        out["governing_fe_mode"].append(m["mode"] + 1)
        for name, sel in paired.items():
            mp = band_minimum(band_Hz, fr, zz, np.zeros(fr.size), pphi, residual, paired=sel, n_freq=n_freq)
            out["paired"][name]["k_paired_N_per_m"].append(mp["k_paired_N_per_m"])
            out["paired"][name]["paired_fe_mode"].append(None if mp["mode_paired"] is None else mp["mode_paired"] + 1)
    out["k_min_low_N_per_m"], out["k_min_high_N_per_m"] = min(out["k_min_N_per_m"]), max(out["k_min_N_per_m"])
    for rec in out["paired"].values():
        ks = [k for k in rec["k_paired_N_per_m"] if k is not None]
        rec["k_paired_low_N_per_m"] = min(ks) if ks else None
        rec["k_paired_high_N_per_m"] = max(ks) if ks else None
    return out
