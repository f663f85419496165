"""FRF correlation, pure maths: measured against model frequency response functions.

Criteria (standard definitions; ``H_x`` measured, ``H_a`` model, both receptances in m/N):

* FRAC, frequency response assurance criterion (Heylen, Lammens & Sas, *Modal Analysis Theory and
  Testing*): one FRF over its frequency lines, the MAC of the two FRF vectors
  (:func:`jointid.correlate.mac.mac`)::

      FRAC = |H_x^H H_a|^2 / ((H_x^H H_x)(H_a^H H_a))

  in [0, 1], 1 for FRFs that differ only by a complex factor (scale-invariant).
* CSAC, cross signature assurance criterion, and CSF, cross signature scale factor (Zang, Grafe &
  Imregun, MSSP 15 (2001): the global shape and amplitude criteria; Dascotte & Strobbe, IMAC 1999):
  at each frequency over the response DOFs measured for one excitation, ``H_x(w)``, ``H_a(w)`` of
  shape ``(n_dof,)``::

      CSAC(w) = |H_x^H H_a|^2 / ((H_x^H H_x)(H_a^H H_a))     (shape agreement, scale-invariant)
      CSF(w)  = 2 |H_x^H H_a| / (H_x^H H_x + H_a^H H_a)         (amplitude agreement)

  both in [0, 1] and 1 where the FRFs agree.  A model ``H_a = s H_x`` (``s > 0``) has CSAC = 1 and
  CSF = ``2 s / (1 + s^2)`` (symmetric in ``s`` and ``1/s``); the scale itself is
  :func:`frf_scale_factor`.  With one response DOF CSAC is 1 by definition: it tells something only over
  several DOFs.
* log-magnitude residual over a band, ``r = log10|H_a| - log10|H_x|`` (decades), and its RMS, given in
  dB as ``20 rms(r)``.

The model FRF is interpolated onto the measured frequency lines (:func:`frf_on_grid`: real and
imaginary parts linearly; compute the model on a grid that holds the measured lines, or one fine
enough at the resonances, :func:`jointid.response.harmonic.resonance_grid`).  :func:`compare_table`
makes the tidy per-FRF table.  The measured dynamic stiffness at the drive point is
:mod:`jointid.response.measured` (it reuses Table 1's :func:`jointid.response.harmonic.dynamic_stiffness`,
a layer above this one).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from jointid.correlate.mac import mac
from jointid.errors import DataError

__all__ = ["COMPARE_COLUMNS", "compare_frf", "compare_table", "csac", "csf", "frac", "frf_on_grid",
           "frf_scale_factor", "log_magnitude_residual"]

COMPARE_COLUMNS = ["state", "point", "direction", "frac", "csac", "csf", "log_rms_dB", "n_freq"]
"""Columns of :func:`compare_table` (criteria dimensionless, the log-magnitude RMS in dB)."""


def frf_on_grid(f_model_Hz, H_model, f_Hz) -> np.ndarray:
    """The model FRF at the measured frequency lines (real and imaginary parts interpolated linearly).

    Parameters
    ----------
    f_model_Hz : array_like, shape (n_model,)
        Strictly increasing model frequencies (Hz).
    H_model : array_like of complex, shape (n_model,) or (n_model, n_dof)
        Model FRF (m/N).
    f_Hz : array_like, shape (n_f,)
        Measured frequency lines (Hz), inside ``[f_model_Hz[0], f_model_Hz[-1]]``.

    Returns
    -------
    ndarray of complex, shape (n_f,) or (n_f, n_dof)
        Model FRF at ``f_Hz`` (m/N); exact at lines the model grid holds.

    Raises
    ------
    DataError
        If the model grid is not increasing or does not cover the measured lines.
    """
    fm = np.asarray(f_model_Hz, float).ravel()
    f = np.asarray(f_Hz, float).ravel()
    H = np.asarray(H_model, complex)
    if fm.size < 2 or np.any(np.diff(fm) <= 0) or H.shape[0] != fm.size:
        raise DataError(f"frf_on_grid: {fm.size} model frequencies for {H.shape[0]} FRF values; give a strictly "
                        "increasing model grid with one FRF value per line")
    if f.size and (f.min() < fm[0] - 1e-9 * fm[-1] or f.max() > fm[-1] + 1e-9 * fm[-1]):
        raise DataError(f"frf_on_grid: measured lines {f.min():.6g}-{f.max():.6g} Hz outside the model grid "
                        f"{fm[0]:.6g}-{fm[-1]:.6g} Hz; compute the model over the measured band")
    cols = H.reshape(fm.size, -1)
    out = np.column_stack([np.interp(f, fm, c.real) + 1j * np.interp(f, fm, c.imag) for c in cols.T])
    return out[:, 0] if H.ndim == 1 else out


def frac(H_meas, H_model) -> float:
    """Frequency response assurance criterion of one FRF over its frequency lines.

    Parameters
    ----------
    H_meas, H_model : array_like of complex, shape (n_f,)
        Measured and model FRF on the same lines (any common unit, e.g. m/N); NaN lines are left out.

    Returns
    -------
    float
        FRAC in [0, 1] (dimensionless), 1 for FRFs equal up to a complex factor; 0 if one is zero.
    """
    x, a = _pair(H_meas, H_model)
    return float(mac(x.ravel(), a.ravel())[0, 0])


def csac(H_meas, H_model) -> np.ndarray:
    """Cross signature assurance criterion at each frequency over the response DOFs.

    Parameters
    ----------
    H_meas, H_model : array_like of complex, shape (n_f, n_dof) or (n_f,)
        Measured and model FRFs of one excitation at ``n_dof`` response DOFs (m/N); a 1-D array is one DOF.

    Returns
    -------
    ndarray, shape (n_f,)
        CSAC(w) in [0, 1] (dimensionless); 0 where either side is zero at every DOF.
    """
    x, a = _pair(H_meas, H_model)
    xa, xx, aa = _products(x, a)
    den = xx * aa
    return np.where(den > 0, np.abs(xa) ** 2 / np.where(den > 0, den, 1.0), 0.0)


def csf(H_meas, H_model) -> np.ndarray:
    """Cross signature scale factor (amplitude criterion) at each frequency over the response DOFs.

    Parameters
    ----------
    H_meas, H_model : array_like of complex, shape (n_f, n_dof) or (n_f,)
        As :func:`csac`.

    Returns
    -------
    ndarray, shape (n_f,)
        CSF(w) = 2|H_x^H H_a| / (H_x^H H_x + H_a^H H_a) in [0, 1] (dimensionless); ``2 s / (1 + s^2)``
        for a model ``s`` times the measurement.
    """
    x, a = _pair(H_meas, H_model)
    xa, xx, aa = _products(x, a)
    den = xx + aa
    return np.where(den > 0, 2.0 * np.abs(xa) / np.where(den > 0, den, 1.0), 0.0)


def frf_scale_factor(H_meas, H_model) -> complex:
    """Least-squares factor ``s`` of ``H_model ~ s H_meas`` over all lines and DOFs,
    ``s = H_x^H H_a / H_x^H H_x`` (dimensionless; the FRF analogue of the modal scale factor)."""
    x, a = _pair(H_meas, H_model)
    ok = np.isfinite(x) & np.isfinite(a)
    xx = float(np.sum(np.abs(x[ok]) ** 2))
    return complex(np.sum(np.conj(x[ok]) * a[ok]) / xx) if xx > 0 else complex(np.nan)


def log_magnitude_residual(f_Hz, H_meas, H_model, band_Hz=None) -> tuple[np.ndarray, np.ndarray, float]:
    """Log-magnitude residual ``r = log10|H_model| - log10|H_meas|`` over a band, and its RMS.

    Parameters
    ----------
    f_Hz : array_like, shape (n_f,)
        Frequency lines (Hz).
    H_meas, H_model : array_like of complex, shape (n_f,)
        Measured and model FRF on those lines (m/N).
    band_Hz : (float, float), optional
        Lines kept, ``lo <= f <= hi`` (Hz); default every line.  Lines where either FRF is zero or not
        finite are left out.

    Returns
    -------
    f_Hz : ndarray, shape (n_used,)
        The lines used (Hz).
    r : ndarray, shape (n_used,)
        Residual in decades (log10 of the magnitude ratio); ``20 r`` is in dB.
    rms : float
        ``sqrt(mean(r^2))`` in decades (NaN when no line is used).
    """
    f = np.asarray(f_Hz, float).ravel()
    x, a = _pair(H_meas, H_model)
    x, a = x.ravel(), a.ravel()
    lo, hi = (-np.inf, np.inf) if band_Hz is None else map(float, band_Hz)
    with np.errstate(divide="ignore", invalid="ignore"):
        keep = (f >= lo) & (f <= hi) & (np.abs(x) > 0) & (np.abs(a) > 0) & np.isfinite(x) & np.isfinite(a)
    r = np.log10(np.abs(a[keep])) - np.log10(np.abs(x[keep]))
    return f[keep], r, float(np.sqrt(np.mean(r**2))) if r.size else float("nan")


def compare_frf(f_meas_Hz, H_meas, f_model_Hz, H_model, band_Hz=None) -> dict:
    """FRAC, CSF and the log-magnitude residual of one measured FRF against a model FRF.

    Parameters
    ----------
    f_meas_Hz : array_like, shape (n_f,)
        Measured lines (Hz).
    H_meas : array_like of complex, shape (n_f,)
        Measured receptance (m/N).
    f_model_Hz : array_like, shape (n_model,)
        Model grid (Hz), covering the measured lines in the band.
    H_model : array_like of complex, shape (n_model,)
        Model receptance (m/N).
    band_Hz : (float, float), optional
        Band of the comparison (Hz); default every measured line.

    Returns
    -------
    dict
        ``f_Hz (n,)`` and ``H_meas``, ``H_model`` ``(n,)`` (m/N) on the measured lines in the band,
        ``frac``, ``csf_mean`` (band mean of the one-DOF CSF), ``scale_factor`` (complex,
        :func:`frf_scale_factor`), ``log_rms`` (decades), ``log_rms_dB``, ``n_freq``.
    """
    f = np.asarray(f_meas_Hz, float).ravel()
    x = np.asarray(H_meas, complex).ravel()
    lo, hi = (-np.inf, np.inf) if band_Hz is None else map(float, band_Hz)
    keep = (f >= lo) & (f <= hi)
    if np.count_nonzero(keep) < 2:
        raise DataError(f"compare_frf: {np.count_nonzero(keep)} measured line(s) in the band {band_Hz} Hz; "
                        "give a band that holds the measurement")
    f, x = f[keep], x[keep]
    a = frf_on_grid(f_model_Hz, H_model, f)
    _, _, rms = log_magnitude_residual(f, x, a)
    return {"f_Hz": f, "H_meas": x, "H_model": a, "frac": frac(x, a), "csf_mean": float(np.mean(csf(x, a))),
            "scale_factor": frf_scale_factor(x, a), "log_rms": rms, "log_rms_dB": 20.0 * rms, "n_freq": int(f.size)}


def compare_table(curves, band_Hz=None) -> pd.DataFrame:
    """The tidy per-FRF table of measured against model FRFs.

    Parameters
    ----------
    curves : sequence of dict
        One per measured FRF: ``state, point, direction`` (str), ``f_meas_Hz`` and ``H_meas`` (Hz, m/N,
        shape ``(n_f,)``), ``f_model_Hz`` and ``H_model`` (Hz, m/N, shape ``(n_model,)``).  The FRFs of
        one state share its excitation (``frf_drive_point``).
    band_Hz : (float, float), optional
        Band of the comparison (Hz); default every measured line.

    Returns
    -------
    DataFrame
        :data:`COMPARE_COLUMNS`: ``frac`` of each FRF; ``csac`` and ``csf`` the band means of CSAC(w)
        and CSF(w) over the response DOFs of the FRF's state (the same on every row of a state, on the
        lines all its FRFs share; CSAC is 1 by definition for a state with one FRF); ``log_rms_dB`` the
        RMS of the log-magnitude residual (dB); ``n_freq`` the lines used.
    """
    rows, per_state = [], {}
    for c in curves:
        r = compare_frf(c["f_meas_Hz"], c["H_meas"], c["f_model_Hz"], c["H_model"], band_Hz)
        per_state.setdefault(str(c["state"]), []).append(r)
        rows.append({"state": str(c["state"]), "point": str(c["point"]), "direction": str(c["direction"]),
                     "frac": r["frac"], "log_rms_dB": r["log_rms_dB"], "n_freq": r["n_freq"]})
    state_means = {s: _state_criteria(rs) for s, rs in per_state.items()}
    for row in rows:
        row["csac"], row["csf"] = state_means[row["state"]]
    return pd.DataFrame(rows, columns=COMPARE_COLUMNS)


def _state_criteria(results: list[dict]) -> tuple[float, float]:
    """Band means of CSAC(w) and CSF(w) over the FRFs of one state, on the lines they all share."""
    common = results[0]["f_Hz"]
    for r in results[1:]:
        common = np.intersect1d(common, r["f_Hz"])
    if common.size == 0:
        return float("nan"), float("nan")
    cols = [(r["H_meas"][np.searchsorted(r["f_Hz"], common)], r["H_model"][np.searchsorted(r["f_Hz"], common)])
            for r in results]
    x = np.column_stack([c[0] for c in cols])
    a = np.column_stack([c[1] for c in cols])
    return float(np.mean(csac(x, a))), float(np.mean(csf(x, a)))


def _pair(H_meas, H_model) -> tuple[np.ndarray, np.ndarray]:
    """Both FRFs as complex arrays of one shape (a 1-D array is ``(n_f,)``), NaN lines kept."""
    x, a = np.asarray(H_meas, complex), np.asarray(H_model, complex)
    if x.shape != a.shape:
        raise DataError(f"measured FRF of shape {x.shape}, model FRF of shape {a.shape}: put the model on the "
                        "measured lines first (frf_on_grid)")
    return x, a


def _products(x: np.ndarray, a: np.ndarray):
    """Per frequency (rows), ``H_x^H H_a``, ``H_x^H H_x`` and ``H_a^H H_a`` over the DOFs (columns),
    NaN entries left out."""
    x2 = x.reshape(x.shape[0], -1)
    a2 = a.reshape(a.shape[0], -1)
    ok = np.isfinite(x2) & np.isfinite(a2)
    x2, a2 = np.where(ok, x2, 0), np.where(ok, a2, 0)
    return (np.sum(np.conj(x2) * a2, axis=1), np.sum(np.abs(x2) ** 2, axis=1), np.sum(np.abs(a2) ** 2, axis=1))
