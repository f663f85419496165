"""Mode-shape residual rows: a measured shape against its paired model mode after best scaling.

    r = (alpha phi - psi) / eps,     alpha = phi^T psi / phi^T phi,

``psi`` the measured shape at its measured DOFs scaled to a noise-free RMS of one, ``phi`` the model
mode there, ``eps`` the shape uncertainty as a fraction of that RMS.  The rows are zero-mean with unit
variance at the truth, so chi-square, p-values and AICc built on them keep their meaning (one ``1 - MAC``
row per mode carries the same information but is biased at the truth).  Used by every fit that takes
shapes: the diagnosis's (:mod:`jointid.diagnosis.shape_residuals`) and the identification's polish
(:func:`jointid.identification.polish.fe_polish`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["normalised_shape", "scaled_residual", "shape_noise_estimate", "MIN_SHAPE_UNCERTAINTY"]

MIN_SHAPE_UNCERTAINTY = 1e-3  # an estimated shape uncertainty is at least 0.1 % (a perfect match is no noise level)


def normalised_shape(psi: np.ndarray, eps: float) -> np.ndarray:
    """A measured shape scaled to a noise-free RMS of one (its RMS over ``sqrt(1 + eps^2)``)."""
    rms = float(np.sqrt(np.mean(psi ** 2)))
    return psi * np.sqrt(1.0 + eps ** 2) / rms if rms > 0 else psi


def scaled_residual(psi: np.ndarray, phi: np.ndarray, dphi: np.ndarray | None, eps: float):
    """``(alpha phi - psi) / eps`` and its derivative ``(n, p)`` from ``dphi (n, p)`` (None: zero)."""
    pp = float(phi @ phi)
    alpha = float(phi @ psi) / pp if pp > 0 else 0.0
    r = (alpha * phi - psi) / eps
    if dphi is None or pp <= 0:
        return r, np.zeros((len(psi), 0 if dphi is None else dphi.shape[1]))
    dalpha = (dphi.T @ psi - 2.0 * alpha * (dphi.T @ phi)) / pp
    return r, (np.outer(phi, dalpha) + alpha * dphi) / eps


def shape_noise_estimate(pairs) -> float:
    """One shape uncertainty from the misfit of paired modes ``pairs`` (``(psi, phi)`` at the measured
    DOFs): ``e^2 = sum |psi - alpha phi|^2 / sum (n_m - 1)`` with ``psi`` at a measured RMS of one, and
    ``eps = e / sqrt(1 - e^2)`` (the noise against the noise-free RMS).  It holds the model's own shape
    error as well as the noise: an upper bound of the noise; at least :data:`MIN_SHAPE_UNCERTAINTY`
    where there is any pair, 0 where there is none."""
    ss, dof = 0.0, 0
    for psi, phi in pairs:
        if len(psi) < 2:
            continue
        r, _ = scaled_residual(normalised_shape(psi, 0.0), phi, None, 1.0)
        ss += float(r @ r)
        dof += len(psi) - 1
    if not dof:
        return 0.0
    e2 = min(ss / dof, 0.5)
    return max(float(np.sqrt(e2 / (1.0 - e2))) if e2 > 0 else 0.0, MIN_SHAPE_UNCERTAINTY)
