"""Damping as an explicit, documented model choice.

The dynamic stiffness at a resonance is ``K_min ~ 2 zeta_r k_r``, so any number derived from a
harmonic analysis depends on how damping is modelled. This module turns one named model into modal
damping ratios (for modal superposition, :func:`modal_damping`) or a damping matrix ``C`` (for a
direct solve, :func:`damping_matrix`). The models:

``"modal"``
    constant (or per-mode given) ratio, ``zeta_r = damping_ratio``.
``"rayleigh"``
    ``C = alpha M + beta K``  ->  ``zeta_r = alpha / (2 w_r) + beta w_r / 2``.
``"joint"``
    dampers in the joints proportional to the joint springs, ``C = eta K_joint`` (``eta`` in s), so
    ``phi_r^T C phi_r = eta e_r w_r^2`` and ``zeta_r = eta w_r e_r / 2``, where
    ``e_r = phi_r^T K_joint phi_r / w_r^2`` is the share of mode r's strain energy in the joints.
    ``C`` is not proportional to ``K``: the modal ratios neglect the off-diagonal modal damping
    (good for light damping and separated modes).
``"measured"``
    ratios identified from the modal test, one per mode.

Scaling note: at a resonance ``K_min ~ 2 zeta_r k_r`` (``k_r`` the modal stiffness at the drive point),
so between two joint states ``K_min`` scales as ``k_r`` with constant ``zeta`` (``(f_on/f_off)^2`` if
the mode's modal mass is unchanged) and as ``k_r w_r e_r`` with joint dashpots: the joint share
``e_r`` changes with the joint stiffness too, so the ratio is ``(f_on/f_off)^3`` only when ``e_r ~ 1``
(and the modal mass is unchanged).  A constant joint loss factor (hysteretic, frequency independent,
:mod:`jointid.response.ranges`) gives ``zeta_r ~ gamma e_r / 2`` and ``K_min ~ k_r e_r``.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp

from jointid.errors import ConfigError, DataError, ModelError, NumericalWarning

__all__ = ["DAMPING_MODELS", "damping_matrix", "joint_energy_share", "modal_damping"]

DAMPING_MODELS = ("modal", "rayleigh", "joint", "measured")

_PARAMS = {
    "modal": ("damping_ratio",),
    "rayleigh": ("alpha_per_s", "beta_s"),
    "joint": ("joint_loss_factor_s", "joint_energy_share"),
    "measured": ("measured",),
}


def _omega(freqs_Hz) -> np.ndarray:
    f = np.asarray(freqs_Hz, dtype=float).ravel()
    if f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise ModelError(f"freqs_Hz = {freqs_Hz!r}: natural frequencies must be finite and > 0 Hz; "
                         "remove rigid-body modes (constrain the model) before assigning damping")
    return 2.0 * np.pi * f


def _check_params(model: str, given: dict) -> None:
    if model not in DAMPING_MODELS:
        raise ConfigError(f"damping.model = {model!r} is unknown; use one of {', '.join(DAMPING_MODELS)}")
    problems = []
    for key in _PARAMS[model]:
        if given.get(key) is None:
            problems.append(f"damping.{key}: missing; required by damping model {model!r}")
    for key, value in given.items():
        if value is not None and key not in _PARAMS[model]:
            owner = next(m for m, keys in _PARAMS.items() if key in keys)
            problems.append(f"damping.{key} is set but damping.model is {model!r}; remove it or set "
                            f"damping.model: {owner}")
    if problems:
        raise ConfigError(problems)


def _per_mode(name: str, value, n: int, *, lo: float = 0.0, hi: float = np.inf, exc=ConfigError):
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    arr = arr.ravel()
    if arr.size != n:
        raise exc(f"damping.{name}: {arr.size} values for {n} modes; give one value or one per mode")
    if not np.all(np.isfinite(arr)) or np.any(arr < lo) or np.any(arr > hi):
        raise exc(f"damping.{name} = {arr.tolist()}: values must be finite and in [{lo}, {hi}]")
    return arr


def modal_damping(freqs_Hz, model: str, *, damping_ratio=None, alpha_per_s=None, beta_s=None,
                  joint_loss_factor_s=None, joint_energy_share=None, measured=None) -> np.ndarray:
    """Modal damping ratio of each mode under the chosen damping model.

    Parameters
    ----------
    freqs_Hz : array_like, shape (n_modes,)
        Undamped natural frequencies (Hz), > 0.
    model : {"modal", "rayleigh", "joint", "measured"}
        Damping model (see the module docstring for the formulas).
    damping_ratio : float or array_like, optional
        ``"modal"``: ratio of critical, scalar or one per mode.
    alpha_per_s, beta_s : float, optional
        ``"rayleigh"``: mass coefficient (1/s) and stiffness coefficient (s), both >= 0.
    joint_loss_factor_s : float, optional
        ``"joint"``: ``eta`` in ``C_joint = eta K_joint`` (s), >= 0.
    joint_energy_share : array_like, shape (n_modes,), optional
        ``"joint"``: strain-energy share ``e_r`` in [0, 1] (see :func:`joint_energy_share`).
    measured : array_like, shape (n_modes,), optional
        ``"measured"``: identified ratios, one per mode.

    Returns
    -------
    ndarray, shape (n_modes,)
        Damping ratios ``zeta_r``.

    Raises
    ------
    ConfigError
        Unknown model, missing parameter, or a parameter belonging to another model.
    DataError
        ``measured`` does not hold one finite ratio >= 0 per mode.
    ModelError
        Non-positive frequencies, or energy shares outside [0, 1].
    """
    given = dict(damping_ratio=damping_ratio, alpha_per_s=alpha_per_s, beta_s=beta_s,
                 joint_loss_factor_s=joint_loss_factor_s, joint_energy_share=joint_energy_share,
                 measured=measured)
    _check_params(model, given)
    w = _omega(freqs_Hz)
    n = w.size
    if model == "modal":
        zeta = _per_mode("damping_ratio", damping_ratio, n)
    elif model == "rayleigh":
        alpha = _per_mode("alpha_per_s", alpha_per_s, 1)[0]
        beta = _per_mode("beta_s", beta_s, 1)[0]
        zeta = alpha / (2.0 * w) + beta * w / 2.0
    elif model == "joint":
        eta = _per_mode("joint_loss_factor_s", joint_loss_factor_s, 1)[0]
        share = np.asarray(joint_energy_share, dtype=float)
        if share.ndim == 0 and n > 1:
            raise ModelError(f"joint_energy_share: one value for {n} modes; give one strain-energy share "
                             "per mode (jointid.response.damping.joint_energy_share)")
        share = np.clip(_per_mode("joint_energy_share", share, n, lo=-1e-9, hi=1.0 + 1e-9, exc=ModelError),
                        0.0, 1.0)
        zeta = eta * w * share / 2.0
    else:  # measured
        zeta = _per_mode("measured", measured, n, exc=DataError)
    if np.any(zeta >= 1.0):
        warnings.warn(f"modal_damping: mode(s) {np.flatnonzero(zeta >= 1).tolist()} are overdamped "
                      f"(zeta = {zeta[zeta >= 1]}); they do not resonate, check the {model!r} parameters",
                      NumericalWarning, stacklevel=2)
    return zeta


def joint_energy_share(phi, freqs_Hz, K_joint) -> np.ndarray:
    """Share of each mode's strain energy stored in the joint springs.

    ``e_r = phi_r^T K_joint phi_r / w_r^2`` for mass-normalised ``phi`` (``phi_r^T K phi_r = w_r^2``).

    Parameters
    ----------
    phi : ndarray, shape (n_dofs, n_modes)
        Mass-normalised mode shapes.
    freqs_Hz : array_like, shape (n_modes,)
        Natural frequencies (Hz), > 0.
    K_joint : sparse matrix or ndarray, shape (n_dofs, n_dofs)
        Stiffness contributed by the joints (N/m).

    Returns
    -------
    ndarray, shape (n_modes,)
        Shares in [0, 1].
    """
    w = _omega(freqs_Hz)
    phi = np.asarray(phi, dtype=float)
    if phi.ndim != 2 or phi.shape[1] != w.size:
        raise ModelError(f"phi has shape {phi.shape}; expected (n_dofs, {w.size}) to match freqs_Hz")
    return np.einsum("ir,ir->r", phi, np.asarray(K_joint @ phi)) / w**2


def damping_matrix(model: str, K, M, *, alpha_per_s=None, beta_s=None, K_joint=None,
                   joint_loss_factor_s=None, phi=None, freqs_Hz=None, zeta=None):
    # many parameters: one keyword per damping model's parameter; each model reads its own
    """Viscous damping matrix ``C`` for a direct harmonic solve.

    ``"rayleigh"``: ``C = alpha M + beta K``. ``"joint"``: ``C = eta K_joint``.
    ``"modal"`` / ``"measured"``: ``C = (M Phi) diag(2 zeta_r w_r) (M Phi)^T``, which damps each mode
    of ``Phi`` with its ratio and leaves modes outside ``Phi`` undamped; exact only with the full
    modal basis and dense, so for small validation models only.

    Parameters
    ----------
    model : str
        One of :data:`DAMPING_MODELS`.
    K, M : sparse matrix or ndarray, shape (n, n)
        Stiffness (N/m) and mass (kg) matrices.
    alpha_per_s, beta_s : float, optional
        Rayleigh coefficients.
    K_joint : sparse matrix or ndarray, optional
        Joint stiffness matrix (part of ``K``), for ``"joint"``.
    joint_loss_factor_s : float, optional
        ``eta`` (s), for ``"joint"``.
    phi, freqs_Hz, zeta : optional
        Mass-normalised modes ``(n, n_modes)``, frequencies (Hz) and ratios, for ``"modal"``/``"measured"``.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n, n)
        Damping matrix in N*s/m.
    """
    if model not in DAMPING_MODELS:
        raise ConfigError(f"damping.model = {model!r} is unknown; use one of {', '.join(DAMPING_MODELS)}")
    K = sp.csr_matrix(K)
    M = sp.csr_matrix(M)
    if model == "rayleigh":
        if alpha_per_s is None or beta_s is None:
            raise ConfigError("damping.alpha_per_s and damping.beta_s are both required by model 'rayleigh'")
        return (float(alpha_per_s) * M + float(beta_s) * K).tocsr()
    if model == "joint":
        if K_joint is None or joint_loss_factor_s is None:
            raise ConfigError("damping model 'joint' needs K_joint and damping.joint_loss_factor_s")
        return (float(joint_loss_factor_s) * sp.csr_matrix(K_joint)).tocsr()
    if phi is None or freqs_Hz is None or zeta is None:
        raise ModelError(f"damping model {model!r} has no physical damping matrix; pass phi, freqs_Hz and "
                         "zeta to build the modal one, or use modal superposition (harmonic.frf_modal)")
    w = _omega(freqs_Hz)
    phi = np.asarray(phi, dtype=float)
    zeta = _per_mode("zeta", zeta, w.size)
    mphi = np.asarray(M @ phi)
    return sp.csr_matrix((mphi * (2.0 * zeta * w)) @ mphi.T)
