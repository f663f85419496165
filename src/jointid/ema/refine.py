"""Each physical pole refined by a local nonlinear least-squares fit, with its covariance.

LSCF linearises the fit (it multiplies through by the denominator), which biases the poles when the
FRFs are noisy.  Here each pole is fitted again around its peak: on the lines within three half-power
bandwidths (at least eight lines) of every FRF, the pole's frequency and damping are the nonlinear
parameters, and its residues, the residues of every other physical pole and a complex constant and
slope per FRF are solved linearly (variable projection).  Each FRF line is weighted by one over the
synthesised |H| (floored at 5 % of the FRF's RMS in the band), as the noise of a hammer test scales
with |H|.  The covariance of frequency and damping is ``s^2 (J^T J)^-1`` with ``s^2`` the weighted
residual variance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from jointid.ema.poles import lsfd, pole_from

__all__ = ["Refined", "refine_pole", "refine_all", "guarded", "local_lines", "modal_terms"]

MAX_HALF_LINES = 50
"""At most this many lines either side of the peak are fitted (the far lines say little about the pole)."""
WEIGHT_FLOOR = 0.05
"""Weights are 1 / max(|H_synth|, this x RMS of the FRF in the local band)."""


@dataclass(frozen=True)
class Refined:
    """A refined pole: frequency (Hz), damping ratio, their 1-sigma, the lines used, and per FRF row the
    Gauss-Newton blocks ``J_i^T J_i`` (n_rows, 2, 2) and ``J_i^T r_i`` (n_rows, 2) at the solution (for the
    bootstrap over rows); ``note`` says whether the refit was kept; ``residual_rms`` is the rms of the weighted
    residuals (relative to |H|: about the noise over |H| where the model fits)."""

    freq_Hz: float
    zeta: float
    sigma_freq_Hz: float
    sigma_zeta: float
    n_lines: int
    success: bool
    row_jtj: np.ndarray | None = None
    row_jtr: np.ndarray | None = None
    note: str = "refitted"
    residual_rms: float = float("nan")


def local_lines(freq_Hz, f0: float, zeta0: float, band_Hz) -> np.ndarray:
    """Indices of the lines within three half-power bandwidths of ``f0`` (at least 4, at most
    ``MAX_HALF_LINES`` lines either side)."""
    freq = np.asarray(freq_Hz, float)
    df = freq[1] - freq[0]
    half = max(min(3 * 2 * zeta0 * f0, MAX_HALF_LINES * df), 4 * df)
    sel = (freq >= max(f0 - half, band_Hz[0])) & (freq <= min(f0 + half, band_Hz[1]))
    return np.flatnonzero(sel)


def modal_terms(w, poles, A) -> np.ndarray:
    """``sum_r A_r / (i w - p_r) + conj(A_r) / (i w - conj(p_r))`` of every row: shape (n_rows, n_w)."""
    iw = 1j * np.asarray(w, float)[:, None]
    poles = np.asarray(poles, complex)[None, :]
    return (np.asarray(A) @ (1 / (iw - poles)).T) + (np.conj(A) @ (1 / (iw - np.conj(poles))).T)


def _projected(x, w, Yw, W, near):
    """Weighted residuals of all rows after the linear parameters are solved (variable projection)."""
    iw = 1j * w[:, None]
    poles = np.concatenate([[pole_from(x[0], x[1])], near])
    g1 = 1 / (iw - poles) + 1 / (iw - np.conj(poles))
    g2 = 1j * (1 / (iw - poles) - 1 / (iw - np.conj(poles)))
    one = np.ones((w.size, 1))
    wn = (w / w.mean())[:, None]
    G = np.hstack([g1, g2, one, 1j * one, wn, 1j * wn])          # (n_b, n_cols)
    WG = W[:, :, None] * G[None, :, :]                           # (n_rows, n_b, n_cols)
    P = np.concatenate([WG.real, WG.imag], axis=1)                # (n_rows, 2 n_b, n_cols)
    Q, _ = np.linalg.qr(P)
    coef = np.einsum("rbc,rb->rc", Q, Yw)
    r = Yw - np.einsum("rbc,rc->rb", Q, coef)
    return r.ravel()


def refine_pole(freq_Hz, H, H_synth, f0: float, zeta0: float, others, band_Hz) -> Refined:
    # many parameters: the FRFs, their synthesis (weights), the start pole, the other poles and the band
    """Refine the pole ``(f0, zeta0)`` on the FRFs ``H`` (n_rows, n_f).  ``others`` is ``(poles,
    residues (n_rows, n_others))`` of the other physical poles (global LSFD), whose terms are subtracted."""
    idx = local_lines(freq_Hz, f0, zeta0, band_Hz)
    w = 2 * np.pi * np.asarray(freq_Hz, float)[idx]
    f_lo, f_hi = w[0] / 2 / np.pi, w[-1] / 2 / np.pi
    o_poles, o_res = others
    of = np.abs(o_poles) / (2 * np.pi)
    inside = (of >= f_lo) & (of <= f_hi)
    near = o_poles[inside]
    o_poles, o_res = o_poles[~inside], o_res[:, ~inside]
    Hs = np.abs(H_synth[:, idx])
    rms = np.sqrt(np.mean(np.abs(H[:, idx]) ** 2, axis=1, keepdims=True))
    W = 1.0 / np.maximum(Hs, WEIGHT_FLOOR * rms)
    Hc = H[:, idx] - (modal_terms(w, o_poles, o_res) if len(o_poles) else 0.0)
    Yw = np.concatenate([(W * Hc).real, (W * Hc).imag], axis=1)
    n_rows = H.shape[0]
    x0 = np.array([f0, zeta0])
    sol = least_squares(_projected, x0, args=(w, Yw, W, near), x_scale=np.array([zeta0 * f0, zeta0]),
                        bounds=([f_lo, 1e-6], [f_hi, 0.5]), method="trf")
    n_lin = n_rows * (6 + 2 * near.size)
    dof = max(sol.fun.size - n_lin - 2, 1)
    s2 = 2 * sol.cost / dof
    try:
        cov = s2 * np.linalg.inv(sol.jac.T @ sol.jac)
        sig = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        sig = np.array([np.nan, np.nan])
    J = sol.jac.reshape(n_rows, -1, 2)
    r = sol.fun.reshape(n_rows, -1)
    return Refined(float(sol.x[0]), float(sol.x[1]), float(sig[0]), float(sig[1]), int(idx.size), bool(sol.success),
                   np.einsum("rki,rkj->rij", J, J), np.einsum("rki,rk->ri", J, r), residual_rms=float(np.sqrt(s2)))


def refine_all(freq_Hz, H, freqs_Hz, zetas, band_Hz, n_pass: int = 3) -> list[Refined]:
    # many parameters: the FRFs, the start poles, the band and the passes
    """Refine every pole in turn, ``n_pass`` times: each pass subtracts the other poles' terms of a global
    LSFD at the latest poles (Gauss-Seidel over the poles)."""
    f = np.array(freqs_Hz, float)
    z = np.array(zetas, float)
    out = []
    for _ in range(n_pass):
        res = lsfd(freq_Hz, H, pole_from(f, z), band_Hz)
        poles = pole_from(f, z)
        out = []
        for m in range(f.size):
            others = (np.delete(poles, m), np.delete(res.A, m, axis=1))
            r = refine_pole(freq_Hz, H, res.synth, f[m], z[m], others, band_Hz)
            out.append(r)
        f = np.array([r.freq_Hz for r in out])
        z = np.array([r.zeta for r in out])
    return out


def guarded(refined: list[Refined], freqs_Hz, zetas, scatter_Hz, scatter_zeta, tol_pct: float) -> list[Refined]:
    # many parameters: the refits, the LSCF poles and their scatter over orders, the tolerance
    """The refits, each replaced by its LSCF pole when it moved more than ``tol_pct`` in frequency (a mode
    the LSCF did not resolve pulls the local fit away).  Such a pole's sigma is the larger of the
    distance between the two estimates and its scatter over orders."""
    out = []
    for r, f, z, sf, sz in zip(refined, freqs_Hz, zetas, scatter_Hz, scatter_zeta):
        moved = abs(r.freq_Hz - f) / f
        if moved <= tol_pct / 100:
            out.append(r)
            continue
        out.append(Refined(float(f), float(z), max(abs(r.freq_Hz - f), sf), max(abs(r.zeta - z), sz), r.n_lines,
                           False, None, None, f"refit moved {100 * moved:.2f} %: LSCF pole kept", r.residual_rms))
    return out
