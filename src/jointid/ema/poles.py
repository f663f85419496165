"""Poles by LSCF over model orders (sdypy-EMA) and residues by LSFD with their covariance.

LSCF fits one common denominator to every FRF of a state at model orders 2, 4, ... ``max_order``
(:func:`lscf_chart`, sdypy-EMA's ``Model.get_poles``).  LSFD (:func:`lsfd`) then fits, per FRF, the
residues of given poles with a lower (mass, ``-1/w^2``) and an upper (stiffness, constant) residual
term, by linear least squares; it is sdypy-EMA's LSFD in the receptance form, written here because
its parameter covariance gives each residue's noise.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from jointid.errors import DataError

__all__ = ["PoleChart", "lscf_chart", "lsfd", "Residues", "pole_freq_damping", "pole_from"]


@dataclass(frozen=True)
class PoleChart:
    """The poles of every model order.

    Attributes
    ----------
    orders : ndarray of int, shape (n_orders,)
        Model orders 2, 4, ... (poles per order, conjugates included).
    poles : list of ndarray of complex
        Per order, the poles (rad/s, positive imaginary part) inside the band with 0 < zeta < max.
    band_Hz : tuple of float
    """

    orders: np.ndarray
    poles: list
    band_Hz: tuple


def pole_freq_damping(poles) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequency ``|lambda| / 2 pi`` (Hz) and damping ratio ``-Re lambda / |lambda|``."""
    p = np.asarray(poles, complex)
    return np.abs(p) / (2 * np.pi), -p.real / np.maximum(np.abs(p), 1e-300)


def pole_from(freq_Hz, zeta) -> np.ndarray:
    """The pole ``-zeta w + i w sqrt(1 - zeta^2)`` of a natural frequency (Hz) and damping ratio."""
    w = 2 * np.pi * np.asarray(freq_Hz, float)
    z = np.asarray(zeta, float)
    return -z * w + 1j * w * np.sqrt(1 - z**2)


def lscf_chart(freq_Hz, H, band_Hz, max_order: int, max_damping: float, decay_per_s: float = 0.0) -> PoleChart:
    """LSCF poles of the FRFs ``H`` (n_rows, n_f) at orders 2..max_order, kept when physical-looking.

    ``decay_per_s`` (an exponential window's added decay, 1/s) is added back to every pole's real part.
    """
    from sdypy import EMA  # noqa: PLC0415  (heavy; only the EMA needs it)

    lo, hi = map(float, band_Hz)
    freq = np.asarray(freq_Hz, float)
    if not freq[0] <= lo < hi <= freq[-1]:
        raise DataError(f"analysis band [{lo:g}, {hi:g}] Hz is not inside the FRFs' band "
                        f"[{freq[0]:g}, {freq[-1]:g}] Hz — set ema.band_Hz inside it")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = EMA.Model(frf=np.asarray(H, complex), freq=freq, lower=lo, upper=hi,
                          pol_order_high=max(2, int(max_order) // 2), frf_form="receptance")
        model.get_poles(method="lscf", show_progress=False)
    orders, kept = [], []
    for k, poles in enumerate(model.all_poles):
        p = np.asarray(poles, complex)
        p = p[np.isfinite(p) & (p.imag > 0)] + decay_per_s
        f, z = pole_freq_damping(p)
        keep = (f > lo) & (f < hi) & (z > 0) & (z < max_damping)
        orders.append(2 * (k + 1))
        kept.append(p[keep][np.argsort(f[keep])])
    return PoleChart(np.asarray(orders), kept, (lo, hi))


@dataclass(frozen=True)
class Residues:
    """LSFD residues of the FRFs at given poles.

    Attributes
    ----------
    A : ndarray of complex, shape (n_rows, n_poles)
        Residue of each pole in each FRF (m/N rad/s).
    sigma_A : ndarray, shape (n_rows, n_poles)
        1-sigma of ``|A|`` from the fit's residual and covariance (per real component, rms).
    synth : ndarray of complex, shape (n_rows, n_f)
        The synthesised FRFs on the band's lines (NaN outside the band).
    """

    A: np.ndarray
    sigma_A: np.ndarray
    synth: np.ndarray


def _basis(w, poles) -> np.ndarray:
    """Complex basis columns: per pole ``a`` and ``b`` of ``A = a + ib`` (with its conjugate pole),
    then lower (``-1/w^2``) and upper (1) residuals, each with a real and an imaginary coefficient."""
    iw = 1j * w[:, None]
    g1 = 1 / (iw - poles[None, :]) + 1 / (iw - np.conj(poles)[None, :])
    g2 = 1j * (1 / (iw - poles[None, :]) - 1 / (iw - np.conj(poles)[None, :]))
    low = -1 / w[:, None] ** 2
    one = np.ones_like(low)
    return np.hstack([g1, g2, low, 1j * low, one, 1j * one])


def lsfd(freq_Hz, H, poles, band_Hz, max_lines: int | None = None) -> Residues:
    """Residues of ``poles`` in each FRF of ``H`` (n_rows, n_f), fitted on the band's lines (every k-th
    line when the band has more than ``max_lines``, for a quick fit)."""
    freq = np.asarray(freq_Hz, float)
    poles = np.asarray(poles, complex)
    sel = np.flatnonzero((freq >= band_Hz[0]) & (freq <= band_Hz[1]))
    if max_lines and sel.size > max_lines:
        sel = sel[:: int(np.ceil(sel.size / max_lines))]
    w = 2 * np.pi * freq[sel]
    G = _basis(w, poles)
    P = np.vstack([G.real, G.imag])
    scale = np.linalg.norm(P, axis=0)
    scale[scale == 0] = 1.0
    Ps = P / scale
    Y = np.vstack([H[:, sel].real.T, H[:, sel].imag.T])
    Q, R = np.linalg.qr(Ps)
    Rinv = scipy.linalg.pinv(R)                                      # R is small: (n_par, n_par)
    coef = Rinv @ (Q.T @ Y)
    fit = Ps @ coef
    dof = max(Y.shape[0] - Ps.shape[1], 1)
    s2 = np.sum((Y - fit) ** 2, axis=0) / dof                       # per row
    cov_diag = np.sum(Rinv**2, axis=1) / scale**2                    # diag((P^T P)^-1), unit noise
    coef = coef / scale[:, None]
    n = poles.size
    A = (coef[:n] + 1j * coef[n:2 * n]).T
    var = (cov_diag[:n] + cov_diag[n:2 * n])[None, :] / 2 * s2[:, None]
    synth = np.full(H.shape, np.nan, complex)
    synth[:, sel] = (G @ coef).T
    return Residues(A=A, sigma_A=np.sqrt(var), synth=synth)
