"""Real mode shapes from LSFD residues, over one or more references, with their noise and quality.

With several references, the residues of a mode form a matrix ``R`` (response DOF x reference) of rank
one, ``R = phi l^T``; its first singular vector is the shape.  When the references do not share their
response DOFs, the reference with the largest residues gives the shape.  The complex shape is rotated
to its best real direction (``theta = angle(sum u^2) / 2``) and its real part kept; MPC (modal phase
collinearity, 1 for a real mode) says how real it was.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

__all__ = ["ModeShape", "real_shape", "mpc"]


@dataclass(frozen=True)
class ModeShape:
    """A real mode shape at measured DOFs.

    Attributes
    ----------
    dofs : list of (point, direction)
    value : ndarray, shape (n_dofs,)
        Real shape, largest magnitude +1.
    sigma : ndarray, shape (n_dofs,)
        1-sigma noise of each value (same scale), from the LSFD covariance.
    mpc : float
        Modal phase collinearity of the complex shape (0..1).
    real_share : float
        Share of the complex shape's energy in the real part kept.
    """

    dofs: list
    value: np.ndarray
    sigma: np.ndarray
    mpc: float
    real_share: float


def mpc(u) -> float:
    """Modal phase collinearity of a complex vector (1: all components in phase or anti-phase)."""
    x, y = np.real(u), np.imag(u)
    sxx, syy, sxy = x @ x, y @ y, x @ y
    den = (sxx + syy) ** 2
    return float(((sxx - syy) ** 2 + 4 * sxy**2) / den) if den > 0 else 0.0


def _matrix(rows: pd.DataFrame, values: np.ndarray):
    """``(dofs, refs, M)``: ``values`` per row as a DOF x reference matrix (NaN where not measured)."""
    dof_codes, dofs = pd.factorize(pd.MultiIndex.from_arrays([rows["point"], rows["direction"]]))
    ref_codes, refs = pd.factorize(pd.MultiIndex.from_arrays([rows["ref_point"], rows["ref_direction"]]))
    M = np.full((len(dofs), len(refs)), np.nan, dtype=values.dtype)
    M[dof_codes, ref_codes] = values
    return list(dofs), list(refs), M


def real_shape(rows: pd.DataFrame, A, sigma_A) -> ModeShape:
    """The real shape of one mode from its residues ``A`` (n_rows,) and their 1-sigma ``sigma_A``."""
    dofs, _, R = _matrix(rows, np.asarray(A, complex))
    _, _, S = _matrix(rows, np.asarray(sigma_A, float))
    if np.isnan(R).any():
        j = int(np.nanargmax(np.nansum(np.abs(R) ** 2, axis=0)))
        keep = ~np.isnan(R[:, j])
        dofs = [d for d, k in zip(dofs, keep) if k]
        u, s = R[keep, j], S[keep, j]
    else:
        U, sv, Vh = np.linalg.svd(R, full_matrices=False)
        v = Vh[0].conj()
        u = R @ v
        s = np.sqrt((S**2) @ (np.abs(v) ** 2))
    theta = 0.5 * np.angle(np.sum(u**2))
    rot = u * np.exp(-1j * theta)
    value = rot.real
    share = float(value @ value / max(np.vdot(u, u).real, 1e-300))
    k = int(np.argmax(np.abs(value)))
    scale = value[k]
    return ModeShape(dofs, value / scale, s / abs(scale), mpc(u), share)
