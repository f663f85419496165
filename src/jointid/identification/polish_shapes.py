"""Measured shapes in the identification's polish (docs/effects.md, "Shapes in the fit").

Where a state has measured shapes, every measured mode adds its shape rows
(:mod:`jointid.correlate.shape_rows`) to the Gauss-Newton polish of :func:`jointid.identification.polish.fe_polish`,
and the frequency rows are taken in units of their stated noise so that the two kinds of rows add.
The frequency rows and the shape rows are then judged as two blocks, each widened by its own lack of
fit (``max(1, chi2 / dof)`` of the block), so that many well-fitting shape rows cannot hide an
understated frequency noise; a shape's rows move together within a mode, so the intervals take the
cluster-robust variance (one cluster per measured mode) where it is wider.

* :func:`shape_sensitivity` - ``d shape / d log10 theta`` at the probe by modal superposition;
* :func:`shape_rows` - the rows, their Jacobian and the clusters;
* :func:`block_covariance` - the covariance of the log10 parameters from both blocks.
"""

from __future__ import annotations

import numpy as np

from jointid.correlate.shape_rows import normalised_shape, scaled_residual, shape_noise_estimate
from jointid.fe.shape_derivative import CLOSE_MODE_GAP
from jointid.identification.model_error import cluster_factor

__all__ = ["shape_sensitivity", "shape_rows", "start_uncertainty", "block_covariance"]


def shape_sensitivity(stiffness: dict, phi: np.ndarray, lam: np.ndarray, probe_shapes: np.ndarray,
                      terms: list[dict[str, float]], theta: np.ndarray, cols) -> np.ndarray:
    """``d shape_j / d log10 theta_i`` at the probe of the modes ``cols``, ``(n_labels, len(cols), n_params)``.

    Modal superposition over the solved modes ``phi`` (mass-normalised, eigenvalues ``lam``, shapes at
    the probe ``probe_shapes``): for a stiffness change ``dK``, ``d phi_j = sum_{k != j} phi_k
    (phi_k^T dK phi_j) / (lambda_j - lambda_k)`` (the mass-normalisation term vanishes without a mass
    change).  The modes left out of the solve are left out of the sum: a Jacobian for Gauss-Newton,
    whose objective stays exact.  Modes closer than :data:`jointid.fe.shape_derivative.CLOSE_MODE_GAP`
    are left out of each other's sum too (their rotation into each other holds only over a step far
    below their gap: :mod:`jointid.fe.shape_derivative`)."""
    cols = np.asarray(cols, int)
    out = np.zeros((probe_shapes.shape[0], len(cols), len(theta)))
    for i, (tm, th) in enumerate(zip(terms, theta)):
        KP = sum(c * (stiffness[t] @ phi[:, cols]) for t, c in tm.items())  # (dofs, len(cols))
        G = phi.T @ KP  # (n_modes, len(cols)): phi_k^T dK phi_j
        gap = lam[cols][None, :] - lam[:, None]
        close = np.abs(gap) < CLOSE_MODE_GAP * np.maximum(np.abs(lam[cols])[None, :], np.abs(lam)[:, None])
        C = np.where(close, 0.0, G / np.where(close, 1.0, gap))
        C[cols, np.arange(len(cols))] = 0.0
        out[:, :, i] = (probe_shapes @ C) * th * np.log(10)
    return out


def start_uncertainty(shapes: np.ndarray, model_shapes: np.ndarray, index) -> float:
    """The shape uncertainty estimated at the start from the misfit of the paired modes (an upper bound
    of the noise; :func:`jointid.correlate.shape_rows.shape_noise_estimate`)."""
    pairs = []
    for j, m in enumerate(index):
        ok = np.isfinite(shapes[:, j])
        if m >= 0 and ok.sum() >= 2:
            pairs.append((shapes[ok, j], model_shapes[ok, m]))
    return shape_noise_estimate(pairs)


def shape_rows(shapes: np.ndarray, eps: float, model_shapes: np.ndarray, index, dshape: np.ndarray):
    """``(r, J, modes)``: the shape rows of every measured mode with a shape at two or more DOFs against
    its paired model mode (``index[j]``; ``dshape`` from :func:`shape_sensitivity` for those modes, in
    the order of ``index``), and per row the measured mode it belongs to."""
    r, J, modes = [], [], []
    for j, m in enumerate(index):
        ok = np.isfinite(shapes[:, j])
        if ok.sum() < 2:
            continue
        psi = normalised_shape(shapes[ok, j], eps)
        rj, Jj = scaled_residual(psi, model_shapes[ok, m], dshape[ok, j, :], eps)
        r.append(rj)
        J.append(Jj)
        modes += [j] * len(rj)
    p = dshape.shape[2]
    if not r:
        return np.zeros(0), np.zeros((0, p)), np.zeros(0, int)
    return np.concatenate(r), np.vstack(J), np.asarray(modes, int)


def block_covariance(J: np.ndarray, r: np.ndarray, n_freq: int, n_params: int, modes: np.ndarray) -> dict:
    """The covariance of the log10 parameters from both blocks (rows in units of their stated noise:
    ``n_freq`` frequency rows first, then the shape rows, ``modes`` their measured mode).

    Each block is widened by its own ``c = max(1, chi2 / dof)`` (the frequency block's dof ``n_freq -
    n_params``, the shape block's its rows less one scale per mode); then, with every measured mode a
    cluster (its frequency row, if any, and its shape rows), the covariance is widened by the largest
    ratio of the cluster-robust (sandwich) variance to it (Liang and Zeger 1986), at least 1.

    Returns ``cov``, ``chi2``/``dof`` of the frequency block and ``shape_chi2``/``shape_dof``/
    ``shape_c_hat``, ``cluster_factor``."""
    rf, rs = r[:n_freq], r[n_freq:]
    n_modes = len(np.unique(modes))
    dof_f, dof_s = max(n_freq - n_params, 1), max(len(rs) - n_modes, 1)
    chi2_f, chi2_s = float(rf @ rf), float(rs @ rs)
    c_f, c_s = max(1.0, chi2_f / dof_f), max(1.0, chi2_s / dof_s)
    w = np.concatenate([np.full(n_freq, 1.0 / c_f), np.full(len(rs), 1.0 / c_s)])
    Jw = J * np.sqrt(w)[:, None]
    cov = np.linalg.pinv(Jw.T @ Jw)
    groups: dict = {}
    for k in range(n_freq):  # measured mode k's frequency row; the misfit rows after them each alone
        groups.setdefault(k, []).append(k)
    for k, m in enumerate(modes):
        groups.setdefault(int(m), []).append(n_freq + k)
    factor = cluster_factor(cov, Jw, np.sqrt(w) * r, groups.values(), n_params)
    return {"cov": cov * factor, "chi2": chi2_f, "dof": dof_f, "shape_chi2": chi2_s, "shape_dof": dof_s,
            "shape_c_hat": chi2_s / dof_s, "cluster_factor": factor}
