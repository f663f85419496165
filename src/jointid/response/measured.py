"""The dynamic stiffness at the drive point read from a measured receptance FRF (paper, Table 1).

``K(f) = 1 / H(f)`` (N/m) of a drive-point receptance ``H`` (m/N).  Its minimum over the band is found
by :func:`jointid.response.harmonic.dynamic_stiffness`, the function that gives the model's Table 1
value, on the measured lines.  A measurement has a fixed line spacing, often coarser than the
half-power bandwidth ``2 zeta f_r`` of the resonance, so the lowest line overestimates the minimum;
:func:`measured_dynamic_stiffness` therefore also gives a refined minimum: ``|K|^2`` is a parabola in
``w^2`` through the lowest line and its two neighbours.  For one mode (``|K|^2 = (k - m w^2)^2 +
c^2 w^2``, a quadratic in ``w^2``) that parabola is exact at any line spacing, so the refined minimum
is ``2 zeta k sqrt(1 - zeta^2)`` at ``f_n sqrt(1 - 2 zeta^2)``; near an isolated resonance of a
structure it is close to exact.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from jointid.errors import DataError
from jointid.response.harmonic import dynamic_stiffness

__all__ = ["measured_dynamic_stiffness", "stiffness_frame"]


def stiffness_frame(f_Hz, H) -> pd.DataFrame:
    """``K(f) = 1/H(f)`` of a receptance as a table: ``freq_Hz``, ``K_real_N_per_m``, ``K_imag_N_per_m``,
    ``K_abs_N_per_m``, ``K_abs_N_per_mm`` (one row per line; ``f_Hz`` (n,) in Hz, ``H`` (n,) in m/N)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        k = 1.0 / np.asarray(H, complex).ravel()
    return pd.DataFrame({"freq_Hz": np.asarray(f_Hz, float).ravel(), "K_real_N_per_m": k.real,
                         "K_imag_N_per_m": k.imag, "K_abs_N_per_m": np.abs(k), "K_abs_N_per_mm": np.abs(k) * 1e-3})


def measured_dynamic_stiffness(f_Hz, H, band_Hz=None) -> dict:
    """Minimum dynamic stiffness ``|1/H|`` of a measured drive-point receptance over a band.

    Parameters
    ----------
    f_Hz : array_like, shape (n_f,)
        Measured lines (Hz), strictly increasing.
    H : array_like of complex, shape (n_f,)
        Drive-point receptance (m/N).
    band_Hz : (float, float), optional
        Band of the minimum (Hz); default every line.  At least three lines must lie in it.

    Returns
    -------
    dict
        ``k_dyn_min_N_per_m``, ``k_dyn_min_N_per_mm`` and ``f_at_min_Hz``: the lowest line
        (:func:`jointid.response.harmonic.dynamic_stiffness`); ``k_dyn_min_refined_N_per_m``,
        ``k_dyn_min_refined_N_per_mm``, ``f_at_min_refined_Hz``: the parabola of ``|K|^2`` in ``w^2``
        through the lowest line and its neighbours (the lowest line when the minimum is at a band edge or
        the parabola has no minimum between the neighbours); ``band_Hz`` (the lines used), ``n_freq``,
        ``warnings`` (those of ``dynamic_stiffness``: band edge, under-resolved resonance).
    """
    f = np.asarray(f_Hz, float).ravel()
    h = np.asarray(H, complex).ravel()
    if f.size != h.size:
        raise DataError(f"measured_dynamic_stiffness: {f.size} frequencies and {h.size} FRF values; give one "
                        "receptance value (m/N) per line")
    lo, hi = (-np.inf, np.inf) if band_Hz is None else map(float, band_Hz)
    keep = (f >= lo) & (f <= hi)
    f, h = f[keep], h[keep]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        d = dynamic_stiffness(f, h)
    i = d["index_at_min"]
    k_ref, f_ref = _refined_minimum(f, h, i)
    return {"k_dyn_min_N_per_m": d["k_dyn_min_N_per_m"], "k_dyn_min_N_per_mm": d["k_dyn_min_N_per_m"] * 1e-3,
            "f_at_min_Hz": d["f_at_min_Hz"], "k_dyn_min_refined_N_per_m": k_ref,
            "k_dyn_min_refined_N_per_mm": k_ref * 1e-3, "f_at_min_refined_Hz": f_ref, "band_Hz": d["band_Hz"],
            "n_freq": int(f.size), "warnings": [str(w.message) for w in caught]}


def _refined_minimum(f: np.ndarray, h: np.ndarray, i: int) -> tuple[float, float]:
    """``(|K|_min in N/m, f at it in Hz)`` of the parabola of ``|K|^2`` in ``w^2`` through lines
    ``i - 1, i, i + 1``; the line ``i`` itself when that parabola has no minimum between them."""
    k_i = float(1.0 / np.abs(h[i]))
    if i in (0, f.size - 1):
        return k_i, float(f[i])
    x = (2 * np.pi * f[i - 1:i + 2]) ** 2
    y = 1.0 / np.abs(h[i - 1:i + 2]) ** 2
    xs = (x - x[1]) / (x[2] - x[0])  # centred and scaled: a well-conditioned fit
    a, b, c = np.polyfit(xs, y, 2)
    if not a > 0:
        return k_i, float(f[i])
    v = -b / (2 * a)
    y_min = c - b * b / (4 * a)
    if not (xs[0] <= v <= xs[2]) or not y_min > 0:
        return k_i, float(f[i])
    return float(np.sqrt(y_min)), float(np.sqrt(x[1] + v * (x[2] - x[0])) / (2 * np.pi))
