"""Drive-point model: the modes of the band, the drive vector of a measuring point, and the harmonic
response there with its dynamic stiffness (paper, Table 1).  The FRF maths it uses (modal and direct
FRF, residual flexibility, dynamic stiffness) is :mod:`jointid.response.harmonic`.

Per operating state, at the identified joint parameters:

1. band solve (:func:`solve_band_modes`): every mode up to :data:`MODE_FACTOR` x the band top (2-2.5 x
   is what :func:`jointid.response.harmonic.static_residual` asks for, because the dynamic amplification
   of the truncated modes is not corrected by the static residual);
2. damping ratios from the configured model (:mod:`jointid.response.damping`); measured ratios replace them
   for the modes paired with measured ones, when the dataset has them;
3. drive-point receptance ``H = p^T x`` for the load ``F = p``, where ``p`` is the measuring point's
   row of ``model.probe`` (its interpolation weights: the force is a point load at the measuring
   point, and the response is the displacement there, in the drive direction);
4. modal superposition (:func:`jointid.response.harmonic.frf_modal`) plus the static residual flexibility
   of the truncated modes (:func:`jointid.response.harmonic.static_residual`), which needs ``K``
   nonsingular; a free model (rigid-body modes) falls back to no residual, and says so;
5. dynamic stiffness: the minimum of ``|F/X| = 1/|H|`` over the band on a grid refined at every
   resonance (:func:`jointid.response.harmonic.resonance_grid`), the mode that sets it, and the static
   stiffness ``1/H(0)``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import scipy.sparse as sp

from jointid.response import damping as dm
from jointid.response import harmonic as hm
from jointid.response.harmonic import RIGID_HZ
from jointid.config.typed import Damping
from jointid.errors import ConfigError, DataError, ModelError, NumericalWarning
from jointid.fe.modal import (SURVEY_TOL, Modes, count_modes_below, factorize_shifted, free_dofs, restrict, shift_sigma,
                              solve_modes)
from jointid.geometry.points import dof_labels

__all__ = [
    "MODE_FACTOR",
    "HarmonicResult",
    "drive_vector",
    "harmonic_response",
    "joint_stiffness",
    "modal_damping_ratios",
    "solve_band_modes",
]

MODE_FACTOR = 2.5
"""Modes are solved up to this multiple of the band top (at least 2 x, else a warning)."""
MIN_MODE_FACTOR = 2.0
MAX_MODES = 800


# ------------------------------------------------------------------ building blocks
def drive_vector(model, point: str, direction: str = "y") -> np.ndarray:
    """Load / response vector of a measuring point: its row of ``model.probe``.

    Parameters
    ----------
    model : jointid.fe.fem.Model
        Model with measuring points in ``model.meta["points"]``.
    point : str
        Measuring-point name, e.g. ``"T05"``.
    direction : {"x", "y", "z"}
        Global direction of force and response.

    Returns
    -------
    ndarray, shape (n_dofs,)
        Interpolation weights ``p`` (dimensionless): a unit force at the point is the load ``p`` (N),
        the point's displacement is ``p @ u`` (m).
    """
    labels = dof_labels(pd.DataFrame(model.meta["points"]))
    label = f"{point}:{direction}"
    if label not in labels:
        names = sorted({lab.split(":")[0] for lab in labels})
        raise ConfigError(f"harmonic.drive_point/direction: {label!r} is not a measuring-point DOF of the "
                          f"model — use one of {names[0]}..{names[-1]} and x, y or z")
    return np.asarray(model.probe[labels.index(label)].toarray()).ravel()


@dataclass
class ShiftedFactor:
    """A factorisation of ``K - sigma M`` on the free DOFs ``free``, kept for reuse (release it with
    ``free_memory()``)."""

    fac: object
    sigma: float
    free: np.ndarray

    def solve(self, b):
        return self.fac.solve(b)

    def free_memory(self):
        self.fac.free()


def solve_band_modes(K, M, f_top_Hz: float, *, fixed=None, n_start: int = 20, shift_Hz: float = -10.0,
                     backend: str = "auto", factor: float = MODE_FACTOR, max_modes: int = MAX_MODES,
                     progress=None, keep_factor: bool = False, ordering=None):
    # many parameters: the band solve's options, keyword with defaults
    # long by its numpydoc (47 lines); the body is three steps: Sturm count, solve until complete, warn
    """All modes up to ``factor * f_top_Hz`` (and possibly a few above).

    A Sturm count (:func:`jointid.fe.modal.count_modes_below`, one LDL^T factorisation) tells how many
    modes lie below ``factor * f_top_Hz``; that many plus two are solved at once, and the solve is
    checked against the count (a missed mode is recovered from a random start).  Where no count is
    available (the SuperLU backend had to pivot off the diagonal), ``n_start`` modes are solved and
    the count grows (about as ``f^1.5``, between plate-like ``f`` and solid-like ``f^3``) until the
    highest solved mode reaches ``factor * f_top_Hz``.

    Parameters
    ----------
    K, M : sparse matrix, shape (n_dofs, n_dofs)
        Stiffness (N/m) and mass (kg).
    f_top_Hz : float
        Top of the band (Hz).
    fixed : array_like of int, optional
        Clamped DOFs.
    n_start : int
        Modes in the first attempt.
    shift_Hz, backend
        As :func:`jointid.fe.modal.solve_modes`.
    factor : float
        Target multiple of the band top.
    max_modes : int
        Upper limit on the number of modes.

    ordering : ndarray, optional
        Cached fill-reducing ordering of the free DOFs (``model.ordering``, :func:`jointid.fe.modal.factorize`).
    keep_factor : bool
        Also return the factorisation of ``K - sigma M`` (a :class:`ShiftedFactor`, for
        :func:`jointid.response.harmonic.static_residual`); the caller frees it with ``free_memory()``.

    Returns
    -------
    Modes, or (Modes, ShiftedFactor) with ``keep_factor``
        ``freqs_Hz (n,)``, mass-normalised ``phi (n_dofs, n)``.

    Warns
    -----
    NumericalWarning
        If the limit of modes (or of DOFs) stops the solve below ``2 x f_top_Hz``.
    """
    say = progress or (lambda msg: None)
    n_all = K.shape[0]
    free = free_dofs(n_all, fixed)
    n_free = len(free)
    limit = min(int(max_modes), n_free - 2)
    target = factor * float(f_top_Hz)
    n = max(1, min(int(n_start), limit))
    Kf, Mf = restrict(sp.csr_matrix(K), free), restrict(sp.csr_matrix(M), free)
    count = count_modes_below(Kf, Mf, target, backend, ordering)
    if count is not None:
        n = max(1, min(count + 2, limit))
        say(f"harmonic: Sturm count {count} modes below {target:.0f} Hz")
    sigma = shift_sigma(shift_Hz)
    shifted = ShiftedFactor(factorize_shifted(Kf, Mf, sigma, backend, ordering), sigma, free)
    try:  # one factorisation serves every attempt (and the static solve, with keep_factor)
        seed = None
        while True:
            modes = solve_modes(K, M, n, shift_Hz=shift_Hz, fixed=fixed, backend=backend, factor=shifted.fac,
                                v0_seed=seed, tol=SURVEY_TOL)  # the band's completeness: the Sturm count
            top = float(modes.freqs_Hz[-1])
            found = int(np.count_nonzero(modes.freqs_Hz < target))
            say(f"harmonic: {n} modes up to {top:.0f} Hz (target {target:.0f} Hz)")
            if n >= limit:
                break
            if count is not None:
                if found >= count:
                    break
                if seed is not None:  # a second start missed modes too
                    warnings.warn(f"harmonic: Sturm count {count} modes below {target:.0f} Hz, the solve "
                                  f"found {found}", NumericalWarning, stacklevel=2)
                    break
                n, seed = min(limit, n + count - found), 0  # a missed mode: again from a random start
                continue
            if top >= target:
                break
            ratio = (target / max(top, 1e-3 * target)) ** 1.5
            n = min(limit, max(n + 4, int(math.ceil(1.15 * n * ratio))))
    except BaseException:
        shifted.free_memory()
        raise
    if top < MIN_MODE_FACTOR * f_top_Hz:
        warnings.warn(f"harmonic: the highest of {n} modes is {top:.0f} Hz, below {MIN_MODE_FACTOR:g} x the "
                      f"band top ({f_top_Hz:g} Hz); the FRF near the band top misses the amplification of "
                      "the truncated modes — raise the mode limit or coarsen the mesh", NumericalWarning,
                      stacklevel=2)
    if keep_factor:
        return modes, shifted
    shifted.free_memory()
    return modes


def joint_stiffness(model, k_coeffs: dict) -> sp.csr_matrix:
    """Stiffness of the carriage-rail joint layers alone, ``sum_t k_t K_t`` over the joint-layer terms
    (:func:`jointid.fe.model.joint_layer_terms`; on the rig ``K_top_*``/``K_flank_*``) (N/m)."""
    from jointid.fe.model import joint_layer_terms

    layers = joint_layer_terms(model)
    out = sp.csr_matrix(model.stiffness["K0"].shape)
    for name, c in k_coeffs.items():
        if c and name in layers:
            out = out + c * model.stiffness[name]
    return out.tocsr()


def modal_damping_ratios(damping: Damping, freqs_Hz, *, joint_share=None, measured=None):
    """Damping ratio of every mode, and which source set it.

    Parameters
    ----------
    damping : jointid.config.typed.Damping
        ``harmonic.damping``: ``model`` (modal, rayleigh, joint, measured) and its parameters.
    freqs_Hz : array_like, shape (n_modes,)
        Natural frequencies (Hz); modes below :data:`RIGID_HZ` are rigid-body modes and get 0.
    joint_share : array_like, shape (n_modes,), optional
        Joint strain-energy share of each mode (model ``joint``).
    measured : dict {int: float}, optional
        Measured ratio by mode index (0-based, into ``freqs_Hz``) for the modes paired with measured
        ones. They override the configured model for those modes; with model ``measured`` the other
        modes get the mean measured ratio.

    Returns
    -------
    zeta : ndarray, shape (n_modes,)
    source : list of str
        Per mode: ``"rigid"``, ``"measured"``, ``"<model>"`` or ``"mean measured"``.
    """
    fr = np.asarray(freqs_Hz, dtype=float)
    model = damping.model
    elastic = fr >= RIGID_HZ
    zeta = np.zeros(fr.size)
    source = np.array(["rigid"] * fr.size, dtype=object)
    measured = {int(k): float(v) for k, v in (measured or {}).items() if np.isfinite(v)}
    if model == "measured":
        if not measured:
            raise DataError("harmonic.damping.model is 'measured' but the dataset has no damping ratios of paired "
                            "modes — add a damping_ratio column to modes.csv or choose model modal/rayleigh/joint")
        zeta[elastic] = float(np.mean(list(measured.values())))
        source[elastic] = "mean measured"
    elif np.any(elastic):
        f = fr[elastic]
        needs = {"modal": "damping_ratio", "joint": "joint_loss_factor_s"}.get(model)
        if needs and getattr(damping, needs) is None:
            raise ConfigError(f"harmonic.damping.model is {model!r} but harmonic.damping.{needs} is not given — "
                              f"add it to config.yaml")
        if model == "modal":
            z = dm.modal_damping(f, "modal", damping_ratio=damping.damping_ratio)
        elif model == "rayleigh":
            z = dm.modal_damping(f, "rayleigh", alpha_per_s=damping.alpha_per_s or 0.0,
                                 beta_s=damping.beta_s or 0.0)
        elif model == "joint":
            if joint_share is None:
                raise ModelError("damping model 'joint' needs the joint strain-energy share of every mode")
            z = dm.modal_damping(f, "joint", joint_loss_factor_s=damping.joint_loss_factor_s,
                                 joint_energy_share=np.asarray(joint_share, float)[elastic])
        else:
            raise ConfigError(f"harmonic.damping.model = {model!r} is unknown — use one of "
                              f"{', '.join(dm.DAMPING_MODELS)}")
        zeta[elastic] = z
        source[elastic] = model
    for i, z in measured.items():
        if 0 <= i < fr.size and elastic[i]:
            zeta[i], source[i] = z, "measured"
    if np.any(elastic & (zeta <= 0)):
        warnings.warn("harmonic: some elastic modes have zero damping; their resonances are unbounded and the "
                      "dynamic stiffness tends to 0 — give a damping model that damps every mode",
                      NumericalWarning, stacklevel=2)
    return zeta, list(source)


# ------------------------------------------------------------------ the drive-point response
@dataclass
class HarmonicResult:
    """Drive-point FRF and dynamic stiffness of one state.

    Attributes
    ----------
    f_Hz : ndarray, shape (n_f,)
        Frequency grid (Hz): the configured linear grid plus points around every resonance.
    H : ndarray of complex, shape (n_f,)
        Receptance ``X/F`` (m/N).
    freqs_Hz, zeta : ndarray, shape (n_modes,)
        Natural frequencies (Hz) and damping ratios of the kept modes.
    damping_source : list of str
        Per mode, what set its damping ratio.
    participation : ndarray, shape (n_modes,)
        ``p^T phi_r`` (m/sqrt(kg) per unit load); the modal stiffness at the drive point is
        ``w_r^2 / (p^T phi_r)^2``.
    residual_flexibility_m_per_N : float or None
    static_receptance_m_per_N : float or None
    residual_note : str
    dynamic : dict
        :func:`jointid.response.harmonic.dynamic_stiffness` of the band.
    governing : int
        0-based index of the mode with the largest contribution to ``H`` at the minimum.
    """

    f_Hz: np.ndarray
    H: np.ndarray
    freqs_Hz: np.ndarray
    zeta: np.ndarray
    damping_source: list
    participation: np.ndarray
    residual_flexibility_m_per_N: float | None
    static_receptance_m_per_N: float | None
    residual_note: str
    dynamic: dict
    governing: int
    notes: list = field(default_factory=list)


def harmonic_response(modes: Modes, load, zeta, band_Hz, *, n_freq: int = 1601, residual=None,
                      static_receptance=None) -> HarmonicResult:
    """Drive-point FRF over a band by modal superposition, and its minimum dynamic stiffness.

    Parameters
    ----------
    modes : Modes
        Mass-normalised modes (``phi (n_dofs, n_modes)``, ``freqs_Hz``).
    load : array_like, shape (n_dofs,)
        Load / response vector ``p``.
    zeta : array_like, shape (n_modes,)
        Damping ratios.
    band_Hz : (float, float)
        Band (Hz).
    n_freq : int
        Lines of the linear base grid; points around every resonance in the band are added.
    residual : float, optional
        Static residual flexibility (m/N) of the truncated modes
        (:func:`jointid.response.harmonic.static_residual`).
    static_receptance : float, optional
        ``p^T K^-1 p`` (m/N) for the static stiffness; None = unknown (singular ``K``).

    Returns
    -------
    HarmonicResult
    """
    lo, hi = float(band_Hz[0]), float(band_Hz[1])
    fr = np.asarray(modes.freqs_Hz, dtype=float)
    z = np.asarray(zeta, dtype=float)
    pphi = np.asarray(load, dtype=float).ravel() @ np.asarray(modes.phi)
    grid = np.unique(np.concatenate([np.linspace(lo, hi, int(n_freq)), hm.resonance_grid(lo, hi, fr, z)]))
    r = 0.0 if residual is None else float(residual)
    H = hm.frf_modal(grid, fr, z, pphi, pphi, residual_flexibility=r)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        dyn = hm.dynamic_stiffness(grid, H, None if static_receptance is None else complex(static_receptance))
    notes = [str(w.message) for w in caught]
    for msg in notes:
        warnings.warn(msg, NumericalWarning, stacklevel=2)
    w = 2.0 * np.pi * dyn["f_at_min_Hz"]
    wr = 2.0 * np.pi * fr
    contrib = np.abs(pphi**2 / (wr**2 - w**2 + 2j * z * wr * w))
    return HarmonicResult(f_Hz=grid, H=H, freqs_Hz=fr, zeta=z, damping_source=[], participation=pphi,
                          residual_flexibility_m_per_N=residual, static_receptance_m_per_N=static_receptance,
                          residual_note="", dynamic=dyn, governing=int(np.argmax(contrib)), notes=notes)
