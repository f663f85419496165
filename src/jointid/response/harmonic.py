"""FRF maths: receptances by modal superposition and by direct solve, the static residual flexibility
of truncated modes, and the dynamic stiffness of a band.

Steady-state response to ``F e^{i w t}`` of ``M x'' + C x' + K x = F`` (paper eq. 4, harmonic response
analysis, band 300-3500 Hz). Two ways:

* :func:`frf_modal` - modal superposition of mass-normalised modes with modal damping ratios
  (:mod:`jointid.response.damping`), plus an optional static residual flexibility for the truncated modes
  (:func:`static_residual`, on a factorisation of ``K`` from :func:`static_solver` or the modal solve's);
* :func:`direct_frf` - direct sparse complex solve at each frequency, for validation.

:func:`dynamic_stiffness` reduces a drive-point receptance to the paper's Table 1 quantity: the
minimum of ``|F/X|`` over the band, which sits at a resonance, ``K_min ~ 2 zeta_r k_r``, on a grid
refined at every resonance (:func:`resonance_grid`); :func:`governing_mode` names the mode there.
The drive-point model that uses them is :mod:`jointid.response.drive_point`.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from jointid.errors import DataError, ModelError, NumericalWarning
from jointid.fe.modal import factorize, free_dofs, restrict

__all__ = [
    "RIGID_HZ",
    "direct_frf",
    "dynamic_stiffness",
    "frf_modal",
    "governing_mode",
    "resonance_grid",
    "static_residual",
    "static_solver",
]

RIGID_HZ = 1.0
"""Modes below this frequency (Hz) count as rigid-body modes: ``K`` is singular."""
_RESIDUAL_RTOL = 1e-6  # relative residual |K x - F| / |F| accepted for the static solve
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
        Static residual ``R`` (m/N) of the modes left out (:func:`static_residual`).

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


def _static_by_shifted(shifted, Kf, b, max_iter: int = 50):
    """``K x = b`` from the factorisation of ``A = K - sigma M`` by iterative refinement,
    ``x <- x + A^-1 (b - K x)``: each step shrinks the error by about ``|sigma| / w_1^2`` (1e-3 for a
    -10 Hz shift under a 300 Hz first mode).  None if it does not reach the residual tolerance."""
    x = np.asarray(shifted.solve(b)).ravel()
    nb = max(np.linalg.norm(b), 1e-300)
    for _ in range(max_iter):
        r = b - Kf @ x
        if np.linalg.norm(r) <= 0.01 * _RESIDUAL_RTOL * nb:
            return x
        x = x + np.asarray(shifted.solve(r)).ravel()
    return None


def _static_solution(Kf, b, free, small: bool, backend: str, shifted):
    """``K x = b`` on the free DOFs for :func:`static_residual`: refined on the modal solve's
    factorisation ``shifted`` when it is given (and converges), else by a factorisation of ``K``
    (SuperLU for a ``small`` model, else ``backend``).  Returns ``(x, "")``, or ``(None, note)`` when the
    solve failed or is not accurate (``K`` singular or nearly so)."""
    try:
        x = None
        if shifted is not None and np.array_equal(shifted.free, free):
            x = _static_by_shifted(shifted, Kf, b)  # None if the refinement does not converge
        if x is None and small:
            x = np.asarray(static_solver(Kf)(b)).ravel()
        elif x is None:
            fac = factorize(Kf, backend)
            try:
                x = np.asarray(fac.solve(b)).ravel()
            finally:
                fac.free()
    except (ModelError, RuntimeError, ValueError) as exc:
        return None, f"no residual flexibility: static solve failed ({str(exc).splitlines()[0]})"
    bad = ""
    if not np.all(np.isfinite(x)):
        bad = "the static solution is not finite"
    else:
        res = np.linalg.norm(Kf @ x - b) / max(np.linalg.norm(b), 1e-300)
        if res > _RESIDUAL_RTOL:
            bad = f"the static solve is inaccurate (relative residual {res:.1e})"
    if bad:
        return None, f"no residual flexibility: {bad}; K is (nearly) singular"
    return x, ""


def static_residual(K, load, phi, freqs_Hz, *, fixed=None, backend: str = "auto", shifted=None,
                    response=None, K_free=None):
    # many parameters: the model (K, fixed, K_free), the load and response, the kept modes, the solver to use
    """Static residual flexibility of the modes not kept in ``phi``, or None if ``K`` is singular.

    ``R = q^T K^-1 p - sum_r (q^T phi_r)(p^T phi_r) / w_r^2`` (m/N for a unit load ``p``) with the
    response vector ``q``; at the drive point (``q = p``, the default) ``R = p^T K^-1 p - sum_r
    (p^T phi_r)^2 / w_r^2 >= 0``.  Added to :func:`frf_modal` it restores the static contribution of the
    truncated (higher) modes exactly at 0 Hz.  Their dynamic amplification, ``(f/f_t)^2 / (1 -
    (f/f_t)^2)`` times their static share, is not corrected: keep modes up to about 2-2.5 times the top
    of the band (in the tests, a 40-DOF chain keeping 6 modes is within 1 % up to 0.4 f_7 and not near
    f_7).  ``K`` must be nonsingular: a model with rigid-body modes has no static solution.

    Parameters
    ----------
    K : sparse matrix, shape (n_dofs, n_dofs)
        Stiffness (N/m), before removing ``fixed``.
    load : array_like, shape (n_dofs,)
        Load vector ``p`` (N per unit load; the drive point's :func:`jointid.response.drive_point.drive_vector`).
    phi : ndarray, shape (n_dofs, n_modes)
        Kept mass-normalised modes.
    freqs_Hz : array_like, shape (n_modes,)
        Their frequencies (Hz).
    fixed : array_like of int, optional
        Clamped DOFs (removed from ``K``).
    backend : str
        Factorisation backend (:func:`jointid.fe.modal.factorize`).
    shifted : object with ``solve(b)`` and ``free``, optional
        The modal solve's factorisation of ``K - sigma M`` on the DOFs ``free``
        (:class:`jointid.response.drive_point.ShiftedFactor` of ``solve_band_modes(keep_factor=True)``):
        the static solve then refines on it instead of factorising ``K`` again.
    response : array_like, shape (n_dofs,), optional
        Response vector ``q`` (e.g. a unit vector at a response DOF) for a transfer residual, which
        may have either sign; default the load (drive point).
    K_free : sparse matrix, optional
        ``K`` restricted to the DOFs not in ``fixed`` (:func:`jointid.fe.modal.restrict`), formed once by a
        caller with many loads (default: formed here).

    Returns
    -------
    (R, H0, note) : (float or None, float or None, str)
        Residual flexibility (m/N), static receptance ``q^T K^-1 p`` (m/N) and a one-line note on what
        was done; ``R`` and ``H0`` are None when ``K`` is singular (rigid-body modes, a failed or
        inaccurate static solve).
    """
    fr = np.asarray(freqs_Hz, dtype=float)
    n_rigid = int(np.sum(fr < RIGID_HZ))
    if n_rigid:
        return None, None, (f"no residual flexibility: {n_rigid} rigid-body mode(s) below {RIGID_HZ:g} Hz, so K "
                            "is singular (support.kind free?); FRF from the kept modes only, static stiffness 0")
    p = np.asarray(load, dtype=float).ravel()
    n = K.shape[0]
    free = free_dofs(n, fixed)
    b = p[free]
    Kf = restrict(sp.csr_matrix(K), free) if K_free is None else K_free
    x, failed = _static_solution(Kf, b, free, n < 20000, backend, shifted)
    if failed:
        return None, None, failed
    w2 = (2.0 * np.pi * fr) ** 2
    pphi = p @ np.asarray(phi)
    if response is not None:  # a transfer residual: either sign
        q = np.asarray(response, dtype=float).ravel()
        h0 = float(q[free] @ x)
        r = h0 - float(np.sum((q @ np.asarray(phi)) * pphi / w2))
        return r, h0, f"static transfer residual flexibility of the modes above {fr.max():.0f} Hz: {r:.4g} m/N"
    h0 = float(b @ x)
    r = h0 - float(np.sum(pphi**2 / w2))
    if r < -1e-6 * abs(h0):
        return None, None, (f"no residual flexibility: it came out negative ({r:.3e} m/N); K is ill-conditioned "
                            "or the modes are inaccurate")
    return max(r, 0.0), h0, (f"static residual flexibility of the modes above {fr.max():.0f} Hz: {max(r, 0.0):.4g} "
                             f"m/N ({100 * max(r, 0.0) / h0:.2f} % of the static receptance)")


def direct_frf(K, M, C, load, f_Hz, *, fixed=None, response=None) -> np.ndarray:
    """Receptance by a direct solve of ``(K - w^2 M + i w C) x = p`` at each frequency (for validation).

    One sparse complex LU per frequency; the response is ``q^T x``, at the drive point (``q = p``)
    unless ``response`` is given.

    Parameters
    ----------
    K, M, C : sparse matrix, shape (n_dofs, n_dofs)
        Stiffness (N/m), mass (kg), viscous damping (N*s/m; None = undamped).
    load : array_like, shape (n_dofs,)
        Load vector ``p`` (N per unit load), e.g. a unit vector at the drive DOF.
    f_Hz : array_like, shape (n_f,)
        Frequencies (Hz).
    fixed : array_like of int, optional
        Clamped DOFs.
    response : array_like, shape (n_dofs,) or (n_resp, n_dofs), optional
        Response vector(s) ``q``, e.g. unit vectors at response DOFs; default the load (drive point).

    Returns
    -------
    ndarray of complex, shape (n_f,) or (n_f, n_resp)
        ``q^T x`` in m/N.

    Raises
    ------
    ModelError
        If the dynamic stiffness is singular at a frequency (undamped resonance, rigid-body mode at 0 Hz).
    """
    n = K.shape[0]
    free = free_dofs(n, fixed)
    sub = lambda A: sp.csr_matrix(A)[free][:, free].tocsc()  # noqa: E731
    Kf, Mf = sub(K), sub(M)
    Cf = sp.csc_matrix(Kf.shape) if C is None else sub(C)
    p = np.asarray(load, dtype=float).ravel()[free]
    q = p if response is None else np.asarray(response, dtype=float)[..., free]
    out = np.empty((np.size(f_Hz),) + q.shape[:-1], dtype=complex)
    for k, f in enumerate(np.atleast_1d(f_Hz)):
        w = 2.0 * np.pi * float(f)
        A = (Kf - w**2 * Mf + 1j * w * Cf).tocsc()
        try:
            x = spla.splu(A, permc_spec="MMD_AT_PLUS_A", options={"SymmetricMode": True}).solve(p.astype(complex))
        except RuntimeError as exc:
            raise ModelError(f"direct_frf: dynamic stiffness singular at {f} Hz (undamped resonance or "
                             "rigid-body mode at 0 Hz); add damping or move the frequency grid") from exc
        out[k] = q @ x
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
