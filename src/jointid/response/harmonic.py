"""Frequency response functions and dynamic stiffness.

Steady-state response to ``F e^{i w t}`` of ``M x'' + C x' + K x = F`` (paper eq. 4, harmonic response
analysis, band 300-3500 Hz). Two ways:

* :func:`frf_modal` - modal superposition of mass-normalised modes with modal damping ratios
  (:mod:`jointid.response.damping`), plus an optional static residual flexibility for the truncated modes
  (:func:`residual_flexibility`);
* :func:`frf_direct` - direct sparse complex solve at each frequency, for validation on small models.

:func:`dynamic_stiffness` reduces a drive-point receptance to the paper's Table 1 quantity: the
minimum of ``|F/X|`` over the band, which sits at a resonance, ``K_min ~ 2 zeta_r k_r``.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from jointid.errors import DataError, ModelError, NumericalWarning

__all__ = [
    "dynamic_stiffness",
    "frf_direct",
    "frf_modal",
    "governing_mode",
    "resonance_grid",
    "residual_flexibility",
    "static_solver",
]

_SINGULAR_PIVOT_RATIO = 1e-10  # free 3-D solids give ~1e-16..1e-13; constrained ones >= ~1e-7


def frf_modal(f_Hz, freqs_Hz, zeta, phi_drive, phi_resp, *, residual_flexibility=0.0) -> np.ndarray:
    """Receptance by modal superposition.

    ``H(w) = sum_r phi_resp_r phi_drive_r / (w_r^2 - w^2 + 2 i zeta_r w_r w) + R``

    Parameters
    ----------
    f_Hz : array_like, shape (n_f,)
        Excitation frequencies (Hz).
    freqs_Hz : array_like, shape (n_modes,)
        Undamped natural frequencies (Hz).
    zeta : float or array_like, shape (n_modes,)
        Modal damping ratios.
    phi_drive : array_like, shape (n_modes,)
        Mass-normalised mode shapes at the drive DOF (or the modal forces ``phi^T F`` of a unit
        distributed load).
    phi_resp : array_like, shape (n_modes,) or (n_resp, n_modes)
        Mass-normalised mode shapes at the response DOF(s).
    residual_flexibility : float or array_like, shape (n_resp,)
        Static residual ``R`` (m/N) of the modes left out (:func:`residual_flexibility`).

    Returns
    -------
    ndarray of complex, shape (n_f,) or (n_f, n_resp)
        Receptance X/F in m/N.
    """
    f = np.atleast_1d(np.asarray(f_Hz, dtype=float))
    fr = np.atleast_1d(np.asarray(freqs_Hz, dtype=float))
    n = fr.size
    z = np.asarray(zeta, dtype=float)
    z = np.full(n, float(z)) if z.ndim == 0 else z.ravel()
    pd = np.asarray(phi_drive, dtype=float).ravel()
    pr = np.asarray(phi_resp, dtype=float)
    one_resp = pr.ndim == 1
    pr = pr.reshape(1, -1) if one_resp else pr
    problems = []
    if z.size != n:
        problems.append(f"zeta: {z.size} values for {n} modes; give one ratio or one per mode")
    if pd.size != n:
        problems.append(f"phi_drive: {pd.size} values for {n} modes; give the drive-DOF row of phi")
    if pr.shape[-1] != n:
        problems.append(f"phi_resp: shape {np.shape(phi_resp)}; expected (n_resp, {n}) or ({n},)")
    if problems:
        raise ModelError(problems)
    w = 2.0 * np.pi * f[:, None]
    wr = 2.0 * np.pi * fr[None, :]
    inv = 1.0 / (wr**2 - w**2 + 2j * z[None, :] * wr * w)          # (n_f, n_modes)
    h = inv @ (pd[:, None] * pr.T) + np.asarray(residual_flexibility, dtype=float).reshape(1, -1)
    return h[:, 0] if one_resp else h


def static_solver(K):
    """Factorise a stiffness matrix once and return ``solve(b) -> K^-1 b``.

    Parameters
    ----------
    K : sparse matrix or ndarray, shape (n, n)
        Stiffness matrix (N/m); must be nonsingular (the model constrained, no rigid-body modes).

    Returns
    -------
    callable
        ``solve(b)`` for ``b`` of shape ``(n,)`` or ``(n, k)``.

    Raises
    ------
    ModelError
        If ``K`` is singular or numerically singular (smallest/largest LU pivot < 1e-10).
    """
    K = sp.csc_matrix(K, dtype=float)
    msg = ("the stiffness matrix is singular (rigid-body modes: the model is not constrained); "
           "constrain the model (fix the base or add support springs) or use modal superposition "
           "without residual flexibility")
    try:
        lu = spla.splu(K)
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise ModelError(msg) from exc
    piv = np.abs(lu.U.diagonal())
    if piv.size and piv.min() <= _SINGULAR_PIVOT_RATIO * piv.max():
        raise ModelError(msg + f" [pivot ratio {piv.min() / piv.max():.1e}]")
    return lu.solve


def residual_flexibility(K_solve, F, phi, freqs_Hz, resp_dof):
    """Static residual flexibility of the modes not kept in ``phi``.

    ``R = x_static[resp] - sum_r phi_resp_r (phi_r^T F) / w_r^2`` with ``x_static = K^-1 F``.
    Added to :func:`frf_modal` it restores the static contribution of the truncated (higher) modes
    exactly at 0 Hz. Their dynamic amplification, ``(f/f_t)^2 / (1 - (f/f_t)^2)`` times their static
    share, is not corrected: keep modes up to about 2-2.5 times the top of the band (in the tests, a
    40-DOF chain keeping 6 modes is within 1 % up to 0.4 f_7 and not near f_7).

    Requires ``K`` nonsingular: a model with rigid-body modes has no static solution. Constrain the
    model, or use modal superposition without the residual.

    Parameters
    ----------
    K_solve : callable or sparse matrix
        ``K_solve(b)`` returns ``K^-1 b`` (see :func:`static_solver`); a matrix is factorised here.
    F : array_like, shape (n_dofs,)
        Load vector of the drive (e.g. a unit force at the drive DOF), in N.
    phi : ndarray, shape (n_dofs, n_modes)
        Kept mass-normalised modes.
    freqs_Hz : array_like, shape (n_modes,)
        Their natural frequencies (Hz), all > 0.
    resp_dof : int or array_like of int
        Response DOF(s).

    Returns
    -------
    float or ndarray, shape (n_resp,)
        ``R`` in m per unit load.

    Raises
    ------
    ModelError
        Rigid-body modes among ``freqs_Hz``, a singular ``K``, or a non-finite static solution.
    """
    fr = np.atleast_1d(np.asarray(freqs_Hz, dtype=float))
    rigid = np.flatnonzero(~(fr > 1e-6 * max(fr.max(initial=0.0), 1e-300)))
    if rigid.size:
        raise ModelError(f"residual_flexibility: mode(s) {rigid.tolist()} have ~0 Hz (rigid-body modes), so K "
                         "is singular; constrain the model or use modal superposition without residual")
    if not callable(K_solve):
        K_solve = static_solver(K_solve)
    F = np.asarray(F, dtype=float).ravel()
    phi = np.asarray(phi, dtype=float)
    if phi.ndim != 2 or phi.shape != (F.size, fr.size):
        raise ModelError(f"phi has shape {phi.shape}; expected ({F.size}, {fr.size}) = (n_dofs, n_modes)")
    x = np.asarray(K_solve(F)).ravel()
    if not np.all(np.isfinite(x)):
        raise ModelError("residual_flexibility: the static solution is not finite (singular K); constrain "
                         "the model or use modal superposition without residual")
    w2 = (2.0 * np.pi * fr) ** 2
    resp = np.asarray(resp_dof)
    r = x[resp] - phi[resp] @ ((phi.T @ F) / w2)
    return float(r) if np.ndim(r) == 0 else r


def frf_direct(K, M, C, drive_dof: int, resp_dof, f_Hz) -> np.ndarray:
    """Receptance by direct solution of ``(K - w^2 M + i w C) x = e_drive`` at each frequency.

    Sparse complex LU per frequency; meant for validating modal superposition on small models.

    Parameters
    ----------
    K, M : sparse matrix or ndarray, shape (n, n)
        Stiffness (N/m) and mass (kg).
    C : sparse matrix, ndarray or None
        Viscous damping (N*s/m), e.g. from :func:`jointid.response.damping.damping_matrix`; None = undamped.
    drive_dof : int
        DOF of the unit force.
    resp_dof : int or array_like of int
        Response DOF(s).
    f_Hz : array_like, shape (n_f,)
        Frequencies (Hz).

    Returns
    -------
    ndarray of complex, shape (n_f,) or (n_f, n_resp)
        Receptance in m/N.
    """
    K = sp.csc_matrix(K, dtype=float)
    M = sp.csc_matrix(M, dtype=float)
    C = sp.csc_matrix(K.shape, dtype=float) if C is None else sp.csc_matrix(C, dtype=float)
    n = K.shape[0]
    if M.shape != K.shape or C.shape != K.shape:
        raise ModelError(f"K {K.shape}, M {M.shape} and C {C.shape} must have the same square shape")
    b = np.zeros(n, dtype=complex)
    b[int(drive_dof)] = 1.0
    resp = np.asarray(resp_dof)
    f = np.atleast_1d(np.asarray(f_Hz, dtype=float))
    out = np.empty((f.size,) + resp.shape, dtype=complex)
    for k, fk in enumerate(f):
        w = 2.0 * np.pi * fk
        try:
            x = spla.splu((K - w**2 * M + 1j * w * C).tocsc()).solve(b)
        except RuntimeError as exc:
            raise ModelError(f"frf_direct: dynamic stiffness singular at {fk} Hz (undamped resonance or "
                             "rigid-body mode at 0 Hz); add damping or move the frequency grid") from exc
        out[k] = x[resp]
    return out


def resonance_grid(f_lo_Hz: float, f_hi_Hz: float, freqs_Hz, zeta, *, n_base: int = 400,
                   points_per_halfpower: int = 20, halfwidths: float = 4.0) -> np.ndarray:
    """Frequency grid that resolves every resonance in a band.

    A uniform base grid plus, for each mode in the band, points spaced ``zeta_r f_r /
    points_per_halfpower`` within ``f_r (1 +- halfwidths zeta_r)`` (the half-power bandwidth is
    ``2 zeta_r f_r``). On such a grid the band minimum of ``|1/H|`` is found to well below 1 %.

    Returns
    -------
    ndarray, shape (n_f,)
        Sorted unique frequencies in ``[f_lo_Hz, f_hi_Hz]`` (Hz).
    """
    if not (0 <= f_lo_Hz < f_hi_Hz):
        raise DataError(f"band [{f_lo_Hz}, {f_hi_Hz}] Hz: need 0 <= f_lo < f_hi")
    fr = np.atleast_1d(np.asarray(freqs_Hz, dtype=float))
    z = np.broadcast_to(np.asarray(zeta, dtype=float), fr.shape)
    parts = [np.linspace(f_lo_Hz, f_hi_Hz, n_base)]
    for f0, z0 in zip(fr, z):
        if f_lo_Hz <= f0 <= f_hi_Hz and z0 > 0:
            n = int(np.ceil(2 * halfwidths * points_per_halfpower)) + 1
            parts.append(f0 * (1 + np.linspace(-halfwidths, halfwidths, n) * z0))
    g = np.unique(np.concatenate(parts))
    return g[(g >= f_lo_Hz) & (g <= f_hi_Hz)]


def dynamic_stiffness(f_Hz, H, H0=None) -> dict:
    """Minimum dynamic stiffness ``|1/H|`` over a band (paper, Table 1).

    Parameters
    ----------
    f_Hz : array_like, shape (n_f,)
        Frequencies (Hz), increasing.
    H : array_like of complex, shape (n_f,)
        Drive-point receptance (m/N).
    H0 : complex, optional
        Static receptance ``H(0)`` (m/N), e.g. ``frf_modal([0.0], ...)`` with the residual flexibility.

    Returns
    -------
    dict
        ``k_dyn_min_N_per_m`` (min of ``|1/H|``), ``f_at_min_Hz``, ``index_at_min``,
        ``band_Hz`` ([f_lo, f_hi]), ``k_static_N_per_m`` (``1/|H0|``, or None).

    Warns
    -----
    NumericalWarning
        If the minimum lies at a band edge (it may continue outside the band) or a neighbouring grid
        point exceeds it by > 25 % (the resonance is under-resolved and the minimum overestimated;
        refine the grid, see :func:`resonance_grid`).
    """
    f = np.asarray(f_Hz, dtype=float).ravel()
    h = np.asarray(H, dtype=complex).ravel()
    if f.size != h.size or f.size < 3:
        raise DataError(f"dynamic_stiffness: {f.size} frequencies and {h.size} FRF values; give >= 3 "
                        "matching points")
    if np.any(np.diff(f) <= 0):
        raise DataError("dynamic_stiffness: f_Hz must be strictly increasing; sort the grid")
    with np.errstate(divide="ignore"):
        kd = 1.0 / np.abs(h)
    i = int(np.argmin(kd))
    if i in (0, f.size - 1):
        warnings.warn(f"dynamic_stiffness: minimum at the band edge ({f[i]} Hz); it may lie outside "
                      f"[{f[0]}, {f[-1]}] Hz and is not a resonance in the band", NumericalWarning,
                      stacklevel=2)
    else:
        ratio = max(kd[i - 1], kd[i + 1]) / kd[i]
        if ratio > 1.25:
            warnings.warn(f"dynamic_stiffness: resonance at {f[i]:.6g} Hz under-resolved (neighbour "
                          f"{ratio:.2f}x the minimum); the minimum is overestimated, refine the grid "
                          "(harmonic.resonance_grid)", NumericalWarning, stacklevel=2)
    return {
        "k_dyn_min_N_per_m": float(kd[i]),
        "f_at_min_Hz": float(f[i]),
        "index_at_min": i,
        "band_Hz": [float(f[0]), float(f[-1])],
        "k_static_N_per_m": None if H0 is None else float(1.0 / abs(complex(H0))),
    }


def governing_mode(f_min, freqs_Hz) -> int:
    """Index of the natural frequency nearest to ``f_min`` (the mode that sets ``K_min``)."""
    fr = np.atleast_1d(np.asarray(freqs_Hz, dtype=float))
    if fr.size == 0:
        raise DataError("governing_mode: freqs_Hz is empty; give the natural frequencies in Hz")
    return int(np.argmin(np.abs(fr - float(f_min))))
