"""Exact mode-shape derivatives of a reduced (Rayleigh-Ritz) eigen-solution (Nelson's method, bordered form).

The reduced solver (:class:`jointid.fe.reduced.ReducedSolver`) solves ``K_r(c) y = lambda M_r(c) y`` on its
subspace ``V`` (``K_r = V^T K V``, mass-normalised ``y^T M_r y = 1``).  For a coefficient direction
``(dK, dM)`` of a simple eigenvalue, differentiating the eigen-equation and the normalisation gives

    (K_r - lambda M_r) dy = -(dK_r - lambda dM_r - dlambda M_r) y,     (M_r y)^T dy = -y^T dM_r y / 2,

with ``dlambda = y^T (dK_r - lambda dM_r) y``.  The matrix is singular along ``y``; bordering it with the
normalisation row (Nelson 1976, in the bordered form of Lee, Jung and Lee 1999) makes it regular and the
solution is the exact derivative of the Ritz vector, hence of the probe shapes ``P V y``.  It is exact for
the reduced model, which is the full model's answer to the solver tolerance where the subspace holds the
first-order responses ``A^-1 (dK - lambda dM) phi`` (it is seeded with them per parameter direction).

Close modes.  Where another Ritz value lies within :data:`CLOSE_MODE_GAP` (relative) of ``lambda``, the
derivative's part along that mode, ``(z^T g) / (lambda - lambda_z)``, is the rotation of the two shapes
into each other.  Near a veering it is thousands of times the shapes' other sensitivities and holds only
over a parameter step far below the gap, so one pair of close modes would dominate every Gauss-Newton
step and every score test (it made an elastic base look collinear with the joints on a coarse-rig case).
That part is left out: the derivative is held M-orthogonal to the close modes (one more border row
each).  The residuals themselves stay exact; only their Jacobian leaves out the within-pair rotation.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from jointid.fe.reduced import Solution, pad_to_basis

__all__ = ["CLOSE_MODE_GAP", "close_modes", "reduced_pencil", "probe_shape_derivatives"]

CLOSE_MODE_GAP = 1e-2
"""Two modes whose eigenvalues differ by less than this fraction (0.5 % in frequency) are close: the
rotation of their shapes into each other is left out of the shape derivatives."""


def close_modes(lam_all: np.ndarray, lam: float, gap: float = CLOSE_MODE_GAP) -> np.ndarray:
    """Indices of the eigenvalues of ``lam_all`` within ``gap`` (relative) of ``lam``, the mode itself
    (the one nearest ``lam``) left out."""
    lam_all = np.asarray(lam_all, float)
    if not len(lam_all):
        return np.zeros(0, int)
    d = np.abs(lam_all - lam)
    self_k = int(np.argmin(d))
    near = np.flatnonzero(d < gap * max(abs(lam), 1e-30))
    return near[near != self_k]


def _combine(red: dict, coeffs: dict, base: str | None) -> np.ndarray:
    """``red[base] + sum c_a red[a]`` (``base`` None: the sum alone; an empty direction is zero)."""
    out = red[base].copy() if base is not None else None
    for name, c in coeffs.items():
        if c != 0.0:
            out = c * red[name] if out is None else out + c * red[name]
    if out is None:
        r = next(iter(red.values())).shape[0]
        return np.zeros((r, r))
    return out


def _term_products(red: dict, coeff_dicts: list[dict], Y: np.ndarray) -> dict:
    """``red[name] @ Y`` for every term with a non-zero coefficient in any of ``coeff_dicts``."""
    names = dict.fromkeys(n for d in coeff_dicts for n, c in d.items() if c != 0.0)
    return {n: red[n] @ Y for n in names}


def _applied(products: dict, coeffs: dict, k: int, r: int) -> np.ndarray:
    """``sum c_a (red[a] @ y_k)``: a direction's term derivative applied to mode ``k`` (zero if empty)."""
    out = np.zeros(r)
    for name, c in coeffs.items():
        if c != 0.0:
            out += c * products[name][:, k]
    return out


def reduced_pencil(solver, kc: dict, mc: dict) -> tuple[np.ndarray, np.ndarray]:
    """Reduced stiffness and mass ``(K_r, M_r)`` of ``solver`` at coefficients ``(kc, mc)``."""
    return _combine(solver.Kr, kc, "K0"), _combine(solver.Mr, mc, "M0")


def probe_shape_derivatives(solver, sol: Solution, modes, directions: list[tuple[dict, dict]]) -> np.ndarray:
    """Derivatives of the probe shapes of ``modes`` of ``sol`` along coefficient ``directions``.

    Parameters
    ----------
    solver : ReducedSolver
        The solver that produced ``sol`` (its current basis holds ``sol``'s).
    sol : Solution
    modes : sequence of int
        Mode indices of ``sol``.
    directions : list of (dkc, dmc)
        Coefficient derivatives per parameter (as :meth:`Variant.dcoefficients` gives them).

    Returns
    -------
    ndarray, shape (n_labels, len(modes), len(directions))
        ``d(P V y_i) / dx_j`` of the mass-normalised modes.
    """
    K, M = reduced_pencil(solver, sol.kc, sol.mc)
    r = K.shape[0]
    Y = pad_to_basis(sol.Y, r)
    Y_all = pad_to_basis(sol.Y_all, r)
    modes = [int(i) for i in modes]
    Ys = Y[:, modes]
    # the directions' reduced terms applied to the modes (a product per term, not a matrix per direction)
    KY = _term_products(solver.Kr, [dkc for dkc, _ in directions], Ys)
    MY = _term_products(solver.Mr, [dmc for _, dmc in directions], Ys)
    MYs = M @ Ys
    out = np.zeros((solver.PV.shape[0], len(modes), len(directions)))
    for k, i in enumerate(modes):
        y, lam, My = Ys[:, k], float(sol.lam[i]), MYs[:, k]
        Z = M @ Y_all[:, close_modes(sol.lam_all, lam)]  # the close modes' borders (module docstring)
        nb = 1 + Z.shape[1]
        B = np.zeros((r + nb, r + nb))
        B[:r, :r] = K - lam * M
        B[:r, r] = My
        B[r, :r] = My
        B[:r, r + 1:] = Z
        B[r + 1:, :r] = Z.T
        rhs = np.zeros((r + nb, len(directions)))
        for j, (dkc, dmc) in enumerate(directions):
            dKy, dMy = _applied(KY, dkc, k, r), _applied(MY, dmc, k, r)
            g = dKy - lam * dMy
            dlam = float(y @ g)
            rhs[:r, j] = -(g - dlam * My)
            rhs[r, j] = -0.5 * float(y @ dMy)
        dy = sla.lu_solve(sla.lu_factor(B, check_finite=False), rhs, check_finite=False)[:r]
        out[:, k, :] = solver.PV @ dy
    return out
