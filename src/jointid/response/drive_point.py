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

from jointid.config.datasets import dataset_folder
from jointid.response import damping as dm
from jointid.response import harmonic as hm
from jointid.response.harmonic import RIGID_HZ, static_residual
from jointid.errors import ConfigError, DataError, ModelError, NumericalWarning
from jointid.fe.modal import (Modes, count_modes_below, factorize_shifted, free_dofs, restrict, shift_sigma,
                              solve_modes)
from jointid.geometry.points import dof_labels

__all__ = [
    "MODE_FACTOR",
    "HarmonicResult",
    "drive_vector",
    "frf_frame",
    "harmonic_response",
    "joint_stiffness",
    "modal_damping_ratios",
    "run_harmonic",
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
                                v0_seed=seed)
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
    """Stiffness of the carriage-rail joint layers alone, ``sum_t k_t K_t`` over ``K_top_*``/``K_flank_*`` (N/m)."""
    out = sp.csr_matrix(model.stiffness["K0"].shape)
    for name, c in k_coeffs.items():
        if c and name.startswith(("K_top_", "K_flank_")):
            out = out + c * model.stiffness[name]
    return out.tocsr()


def modal_damping_ratios(damping_cfg: dict, freqs_Hz, *, joint_share=None, measured=None):
    """Damping ratio of every mode, and which source set it.

    Parameters
    ----------
    damping_cfg : dict
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
    model = damping_cfg.get("model", "modal")
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
        if model == "modal":
            z = dm.modal_damping(f, "modal", damping_ratio=damping_cfg["damping_ratio"])
        elif model == "rayleigh":
            z = dm.modal_damping(f, "rayleigh", alpha_per_s=damping_cfg.get("alpha_per_s", 0.0),
                                 beta_s=damping_cfg.get("beta_s", 0.0))
        elif model == "joint":
            if joint_share is None:
                raise ModelError("damping model 'joint' needs the joint strain-energy share of every mode")
            z = dm.modal_damping(f, "joint", joint_loss_factor_s=damping_cfg["joint_loss_factor_s"],
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


def frf_frame(res: HarmonicResult) -> pd.DataFrame:
    """FRF table: ``freq_Hz, H_real_m_per_N, H_imag_m_per_N, H_abs_m_per_N, phase_deg,
    dynamic_stiffness_N_per_m`` (``|F/X|``)."""
    return pd.DataFrame({"freq_Hz": res.f_Hz, "H_real_m_per_N": res.H.real, "H_imag_m_per_N": res.H.imag,
                         "H_abs_m_per_N": np.abs(res.H), "phase_deg": np.degrees(np.angle(res.H)),
                         "dynamic_stiffness_N_per_m": 1.0 / np.abs(res.H)})


# ------------------------------------------------------------------ the workflow stage
def _measured_by_fe_mode(cfg, state, verify_csv) -> tuple[dict, str]:
    """Measured damping ratios by 0-based FE mode index (paired via verify.csv), and a note."""
    from jointid.data.dataset import read_dataset

    if verify_csv is None:
        return {}, "no verify table: measured damping not used"
    folder = dataset_folder(cfg, state)
    try:
        ds = read_dataset(folder)
    except Exception as exc:  # the identify stage has validated the dataset already
        return {}, f"dataset {folder} not readable here ({str(exc).splitlines()[0]}): measured damping not used"
    zm = ds.damping(state) if state in ds.states else None
    if zm is None:
        return {}, f"dataset {folder} has no damping ratios for {state}"
    ver = pd.read_csv(verify_csv)
    out = {}
    for order, fe_mode in zip(ver["order"], ver["fe_mode"]):
        if int(fe_mode) >= 1 and 1 <= int(order) <= len(zm):
            out[int(fe_mode) - 1] = float(zm[int(order) - 1])
    return out, f"measured damping ratios of {len(out)} paired modes from {folder}"


def run_harmonic(cfg: dict, state: str, params_json: str, matrices: str, out_csv: str, out_json: str,
                 out_modes: str | None = None, verify_csv: str | None = None, progress=print) -> dict:
    """The ``harmonic`` workflow stage of one state.

    Reads the identified parameters and the cached model, writes the drive-point FRF (``out_csv``,
    columns of :func:`frf_frame`), the dynamic stiffness summary (``out_json``) and, if given, the
    modes at the measuring points (``out_modes``: ``freqs_Hz (n_modes,)``, ``shapes (n_labels,
    n_modes)``, ``labels``, ``description``, ``zeta``, ``participation``).

    Parameters
    ----------
    cfg : dict
        Sections ``rig, joints, solver, harmonic`` (+ ``states, measurements, datasets`` for measured
        damping).
    state : str
        Operating state (names the dataset's damping ratios).
    params_json, matrices : str
        Identified parameters (identify stage) and the cached model (mesh stage).
    verify_csv : str, optional
        The verify stage's table; its ``fe_mode`` column pairs measured modes with FE modes (for the
        measured damping ratios and the measured order of the governing mode).

    Returns
    -------
    dict
        The content of ``out_json``.
    """
    from jointid import io
    from jointid.fe.model import base_coefficients, load_model

    h = cfg["harmonic"]
    par = io.read_json(params_json)
    theta = {n: float(v["value"]) for n, v in par["parameters"].items()}
    model = load_model(matrices)
    kc, mc = base_coefficients(cfg, model, theta)
    band = [float(b) for b in h["band_Hz"]]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res, modes, desc, dcfg, mnote = _response(cfg, state, model, kc, mc, band, verify_csv, progress)
    notes = [str(w.message) for w in caught]
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    io.write_csv(frf_frame(res), out_csv)
    g = res.governing
    order = None
    if verify_csv:
        ver = pd.read_csv(verify_csv)
        hit = ver.index[ver["fe_mode"] == g + 1]
        order = int(ver.loc[hit[0], "order"]) if len(hit) else None
    k_r = (2 * np.pi * res.freqs_Hz[g]) ** 2 / res.participation[g] ** 2
    dyn = res.dynamic
    R, H0 = res.residual_flexibility_m_per_N, res.static_receptance_m_per_N
    out = {
        "state": state,
        "drive_point": h["drive_point"], "direction": h.get("direction", "y"),
        "band_Hz": band,
        "dynamic_stiffness_N_per_m": dyn["k_dyn_min_N_per_m"],
        "dynamic_stiffness_N_per_mm": dyn["k_dyn_min_N_per_m"] * 1e-3,
        "f_at_min_Hz": dyn["f_at_min_Hz"],
        "static_stiffness_N_per_m": dyn["k_static_N_per_m"],
        "static_stiffness_N_per_mm": None if dyn["k_static_N_per_m"] is None else dyn["k_static_N_per_m"] * 1e-3,
        "governing_mode": {
            "fe_mode": g + 1, "freq_Hz": float(res.freqs_Hz[g]), "description": str(desc["description"][g]),
            "damping_ratio": float(res.zeta[g]), "measured_order": order,
            "modal_stiffness_N_per_m": float(k_r),
            "two_zeta_k_N_per_m": float(2 * res.zeta[g] * k_r),
            "strain_joints": float(desc["strain_joints"][g])},
        "damping": {"config": dcfg, "measured": mnote,
                    "per_mode": [{"fe_mode": i + 1, "freq_Hz": float(f), "damping_ratio": float(z), "source": src}
                                 for i, (f, z, src) in enumerate(zip(res.freqs_Hz, res.zeta, res.damping_source))],
                    "why": _DAMPING_WHY.get(dcfg.get("model", "modal"), "")},
        "modes": {"n_modes": int(res.freqs_Hz.size), "highest_Hz": float(res.freqs_Hz[-1]),
                  "target_Hz": MODE_FACTOR * band[1]},
        "residual": {"used": R is not None, "flexibility_m_per_N": R, "static_receptance_m_per_N": H0,
                     "note": res.residual_note},
        "parameters_N_per_m3": theta,
        "warnings": notes,
        "n_freq": int(res.f_Hz.size),
    }
    io.write_json(out_json, out)
    if out_modes:
        labels = dof_labels(pd.DataFrame(model.meta["points"]))
        io.write_npz(out_modes, freqs_Hz=res.freqs_Hz, shapes=model.probe @ modes.phi, labels=np.array(labels),
                     description=desc["description"].to_numpy().astype(str), zeta=res.zeta,
                     participation=res.participation)
    static = out["static_stiffness_N_per_mm"]
    progress(f"harmonic[{state}]: K_dyn,min = {out['dynamic_stiffness_N_per_mm']:.5g} N/mm at "
             f"{out['f_at_min_Hz']:.1f} Hz (FE mode {g + 1}, {desc['description'][g]}), static "
             f"{'n/a' if static is None else format(static, '.5g')} N/mm")
    return out


def _response(cfg, state, model, kc, mc, band, verify_csv, progress):
    """Modes, residual, damping and FRF of one state (the computing part of :func:`run_harmonic`)."""
    from jointid.fe.describe import describe_modes

    h, s = cfg["harmonic"], cfg["solver"]
    K, M = model.K(kc), model.M(mc)
    modes, shifted = solve_band_modes(K, M, band[1], fixed=model.fixed, n_start=max(int(s["n_modes"]), 12),
                                      shift_Hz=s["shift_Hz"], backend=s["backend"], progress=progress,
                                      keep_factor=True, ordering=model.ordering)
    try:
        p = drive_vector(model, h["drive_point"], h.get("direction", "y"))
        R, H0, note = static_residual(K, p, modes.phi, modes.freqs_Hz, fixed=model.fixed, backend=s["backend"],
                                      shifted=shifted)
    finally:
        shifted.free_memory()
    desc = describe_modes(model, modes.phi, kc, mc)
    progress(f"harmonic[{state}]: {note}")
    dcfg = dict(h.get("damping") or {"model": "modal", "damping_ratio": 0.03})
    measured, mnote = _measured_by_fe_mode(cfg, state, verify_csv)
    share = None
    if dcfg.get("model") == "joint":
        elastic = modes.freqs_Hz >= RIGID_HZ
        share = np.zeros(modes.freqs_Hz.size)
        share[elastic] = dm.joint_energy_share(modes.phi[:, elastic], modes.freqs_Hz[elastic],
                                               joint_stiffness(model, kc))
    zeta, source = modal_damping_ratios(dcfg, modes.freqs_Hz, joint_share=share, measured=measured)
    res = harmonic_response(modes, p, zeta, band, n_freq=int(h["n_freq"]), residual=R, static_receptance=H0)
    res.damping_source, res.residual_note = source, note
    return res, modes, desc, dcfg, mnote


_DAMPING_WHY = {
    "modal": ("constant modal damping ratio: the paper publishes no damping, so one ratio typical of bolted/"
              "guided machine structures is assumed for every mode; K_min then scales as k_r, i.e. as "
              "(f_on/f_off)^2 for a mode whose mass is unchanged"),
    "rayleigh": "Rayleigh damping C = alpha M + beta K with the configured coefficients",
    "joint": ("joint dashpots proportional to the joint springs (c = eta k_joint): damping grows with the "
              "joint stiffness, so K_min scales about as (f_on/f_off)^3"),
    "measured": "measured modal damping ratios of the dataset (mean measured ratio for unpaired modes)",
}
