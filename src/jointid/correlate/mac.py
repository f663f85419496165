"""Modal assurance criterion (MAC): the one implementation used for every shape correlation.

``MAC(a, b) = |a^H b|^2 / ((a^H a)(b^H b))`` between two mode shapes sampled at the same locations
(dimensionless, in [0, 1]; 1 for shapes that differ only by a factor).  A single pair is the 1 x 1
case: ``mac(a, b)[0, 0]`` for two vectors ``a``, ``b``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["mac"]


def mac(phi_a: np.ndarray, phi_b: np.ndarray) -> np.ndarray:
    """Modal assurance criterion between shape sets ``(n_locations, n_a)`` and ``(n_locations, n_b)``.

    Parameters
    ----------
    phi_a, phi_b : array_like, shape (n_locations, n_a) and (n_locations, n_b), or (n_locations,)
        Mode shapes (any unit, real or complex) at the same locations; a 1-D array is one shape.
        A NaN value is a location not measured for that mode: each pair uses the locations finite in
        both of its shapes (a mode whose shape is missing altogether has MAC 0 with every mode, and a
        location missing for one mode does not remove it from the others' pairs).

    Returns
    -------
    ndarray, shape (n_a, n_b)
        MAC in [0, 1] (dimensionless); 0 where a shape is zero at every used location.
    """
    a = np.asarray(phi_a)
    b = np.asarray(phi_b)
    if a.ndim == 1:
        a = a[:, None]
    if b.ndim == 1:
        b = b[:, None]
    ma, mb = ~np.isnan(a), ~np.isnan(b)
    if ma.all() and mb.all():
        num = np.abs(a.conj().T @ b) ** 2
        den = np.outer(np.einsum("ij,ij->j", a.conj(), a).real, np.einsum("ij,ij->j", b.conj(), b).real)
    else:  # per pair, only the locations finite in both shapes
        a0, b0 = np.where(ma, a, 0), np.where(mb, b, 0)
        num = np.abs(a0.conj().T @ b0) ** 2
        den = ((np.abs(a0) ** 2).T @ mb) * (ma.T.astype(float) @ np.abs(b0) ** 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(den > 0, num / den, 0.0)
    return out
