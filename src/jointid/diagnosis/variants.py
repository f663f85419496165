"""Measured states and model variants of the diagnosis (docs/effects.md).

* :class:`StateData` — measured frequencies (and shapes) of one operating state; :func:`dataset_states`
  reads them from a dataset folder.
* :class:`EffectSpec` — an effect inside a variant (start or fixed values, options, fitted parameters).
* :class:`Variant` — the joint parameters (log) plus effects; the coefficients of the affine model and
  their derivatives at a parameter vector ``x``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jointid.correlate import pairing as correlate
from jointid.diagnosis.effects import Effect, apply_effects
from jointid.diagnosis.terms import StateInfo, System, baseline_coefficients
from jointid.errors import DataError
from jointid.config.typed_diagnosis import DiagnosisSettings
from jointid.identification.visibility import dataset_rule


MIN_PAIRING_DOFS = 6
"""Fewest measured DOFs of a shape for the modes to be paired by MAC (two triaxial points)."""


@dataclass
class StateData:
    """Measured data of one state: frequencies (Hz), optional shapes at the probe labels."""

    name: str
    info: StateInfo
    f_meas: np.ndarray
    shapes: np.ndarray | None
    sigma_rel: float | np.ndarray  # relative frequency uncertainty: one for all modes, or one per measured mode
    rule: object = None  # VisibilityRule of the test (None: unpaired model modes are skipped free)
    shape_sigma_rel: float | None = None  # stated shape uncertainty (shape_uncertainty_pct / 100); None: estimated
    known_rel: np.ndarray | None = None  # known model error per measured mode (the mesh's, relative); None: none
    mesh_reference: object = None  # the mesh's correction at the point it was computed
    # (jointid.diagnosis.mesh_error.MeshReference; None: none)
    computed_on_mesh: str | None = None  # a synthetic dataset's mesh digest (conditions.yaml computed_on_mesh)

    def mode_sigma(self) -> np.ndarray:
        """The relative frequency uncertainty of each measured mode ``(n_modes,)``."""
        return np.broadcast_to(np.asarray(self.sigma_rel, float), self.f_meas.shape).astype(float)

    def noise_rms(self) -> float:
        """The root mean square of the modes' relative frequency uncertainties (one number for the state)."""
        return float(np.sqrt(np.mean(self.mode_sigma() ** 2))) if len(self.f_meas) else float(np.mean(self.sigma_rel))

    def mode_known(self) -> np.ndarray:
        """The known error of each measured mode ``(n_modes,)`` (zeros where none is known)."""
        if self.known_rel is None:
            return np.zeros(len(self.f_meas))
        return np.asarray(self.known_rel, float)

    def nearest_mode(self, freqs_Hz) -> np.ndarray:
        """The measured mode nearest to each frequency (index, for the rows of unpaired model modes)."""
        f = np.asarray(freqs_Hz, float)
        if not len(f):
            return np.zeros(0, int)
        return np.abs(np.log(f[:, None] / self.f_meas[None, :])).argmin(axis=1)

    @property
    def pairing_shapes(self) -> np.ndarray | None:
        """The shapes that pair the modes by MAC: None (pair by frequency) without shapes or when no mode
        has a shape at :data:`MIN_PAIRING_DOFS` DOFs (a MAC of two DOFs cannot tell modes apart)."""
        if self.shapes is None or np.isfinite(self.shapes).sum(axis=0).max(initial=0) < MIN_PAIRING_DOFS:
            return None
        return self.shapes


def dataset_states(ds, system: System, settings: DiagnosisSettings, states: list[str] | None = None) -> list[StateData]:
    """:class:`StateData` of the requested states of a :class:`jointid.data.dataset.Dataset`.

    The motor force comes from the dataset's ``conditions.yaml`` (the measured input), else from the
    configured ``states`` (``settings``).  The frequency uncertainty is per mode where modes.csv gives
    ``freq_uncertainty_pct``, else the dataset's ``frequency_uncertainty_pct``, else
    ``identify.frequency_uncertainty_pct``; the shape uncertainty is the dataset's
    ``shape_uncertainty_pct`` (None when not stated: the diagnosis estimates it).  Each state carries the observability rule of its
    test (:func:`state_rule`) unless ``identify.visible_threshold`` is null.
    """
    names = list(states or ds.states)
    missing = [s for s in names if s not in ds.states]
    if missing:
        raise DataError([f"{ds.name}: state {s!r} is not in the dataset — its states are "
                         f"{', '.join(ds.states)}" for s in missing])
    sigma = float(ds.conditions.get("frequency_uncertainty_pct", settings.frequency_uncertainty_pct)) / 100
    shape_pct = ds.conditions.get("shape_uncertainty_pct")
    shape_sigma = None if shape_pct is None else float(shape_pct) / 100
    low = correlate.below_band(ds.name, {s: ds.freqs(s) for s in names}, settings.min_freq_Hz)
    if low:
        raise DataError(low)
    out = []
    for s in names:
        cond = ds.state_conditions(s)
        force = cond.get("em_force_N", settings.em_force_N.get(s, 0.0))
        shapes = None
        if ds.shapes is not None and s in set(ds.shapes["state"]):
            shapes = ds.shape_matrix(s, system.labels)
        per = ds.frequency_sigma_rel(s)  # per-mode uncertainties (modes.csv freq_uncertainty_pct), e.g. an EMA's
        out.append(StateData(s, StateInfo(s, float(force)), ds.freqs(s), shapes, sigma if per is None else per,
                             state_rule(ds, s, system, settings, shapes), shape_sigma,
                             computed_on_mesh=ds.conditions.get("computed_on_mesh")))
    return out


def state_rule(ds, state: str, system: System, settings: DiagnosisSettings, shapes: np.ndarray | None):
    """The observability rule of ``state`` at the system's probe labels
    (:func:`jointid.identification.visibility.dataset_rule`)."""
    return dataset_rule(ds, state, system.labels, system.meta["points"]["point"], shapes,
                        settings.test_setup, f"{ds.name}/conditions.yaml")


@dataclass
class EffectSpec:
    """An effect inside a variant: start/fixed values (physical), options, fitted parameter names."""

    effect: Effect
    values: dict
    options: dict
    free: list

    @classmethod
    def candidate(cls, effect: Effect, options: dict | None = None) -> "EffectSpec":
        """The effect as a candidate: at its null, options over its defaults, every parameter fitted."""
        return cls(effect, effect.null_values(), {**effect.options, **(options or {})},
                   [p.name for p in effect.params])


class Variant:
    """A model variant: the joint parameters (log, shared by all states) plus effects.

    The parameter vector is ``x = [ln theta_1 .. ln theta_p, t_1 .. t_q]`` with ``t`` the
    dimensionless test variables of the free effect parameters (``effects.Param``); ``slots`` lists
    ``(effect number, Param)`` for each of them, in the order of ``x``.
    """

    def __init__(self, system: System, settings: DiagnosisSettings, effects: list[EffectSpec] = (),
                 name: str | None = None, theta_fixed: dict | None = None):
        self.system, self.settings = system, settings
        self.spec = settings.model  # the coefficients are asked for thousands of times
        jp = {p.name: p for p in self.spec.joints.parameters}
        self.theta_fixed = dict(theta_fixed or {})
        self.joint_names = [n for n in jp if n not in self.theta_fixed]
        self.effects = list(effects)
        self.name = name or ("baseline" if not self.effects else
                             "baseline + " + " + ".join(e.effect.name for e in self.effects))
        self.labels = list(self.joint_names)
        lo = [math.log(jp[n].lower_N_per_m3) for n in self.joint_names]
        hi = [math.log(jp[n].upper_N_per_m3) for n in self.joint_names]
        self.slots = []
        for i, spec in enumerate(self.effects):
            for pname in spec.free:
                p = spec.effect.param(pname)
                self.slots.append((i, p))
                self.labels.append(f"{spec.effect.name}.{pname}")
                a, b = p.t_bounds
                lo.append(a)
                hi.append(b if math.isfinite(b) else 1e6)
        self.lower, self.upper = np.array(lo), np.array(hi)
        self.p = len(self.joint_names)

    @property
    def n_params(self) -> int:
        """Length of the parameter vector ``x``."""
        return len(self.labels)

    def x_start(self, theta: dict | None = None) -> np.ndarray:
        """Start vector: ``theta`` (N/m^3) or the geometric mean of the bounds; effect start values."""
        x = 0.5 * (self.lower + self.upper)
        for j, n in enumerate(self.joint_names):
            if theta and n in theta:
                x[j] = math.log(theta[n])
        for k, (i, p) in enumerate(self.slots):
            x[self.p + k] = p.to_t(self.effects[i].values[p.name])
        return np.clip(x, self.lower, self.upper)

    def unpack(self, x) -> tuple[dict, list[dict]]:
        """Joint parameters (N/m^3, fixed ones included) and each effect's physical values at ``x``."""
        theta = {n: math.exp(float(v)) for n, v in zip(self.joint_names, x[: self.p])}
        theta.update(self.theta_fixed)
        vals = [dict(s.values) for s in self.effects]
        for k, (i, p) in enumerate(self.slots):
            vals[i][p.name] = p.from_t(float(x[self.p + k]))
        return theta, vals

    def physical(self, x) -> dict:
        """Parameter values in physical units by label."""
        theta, vals = self.unpack(x)
        out = {n: theta[n] for n in self.joint_names}
        for k, (i, p) in enumerate(self.slots):
            out[self.labels[self.p + k]] = vals[i][p.name]
        return out

    def coefficients(self, x, state: StateInfo) -> tuple[dict, dict]:
        """Term coefficients ``(kc, mc)`` at ``x`` in ``state`` (baseline, then the effects in order)."""
        theta, vals = self.unpack(x)
        kc, mc = baseline_coefficients(self.system, self.spec, theta)
        active = [(s.effect, v, s.options) for s, v in zip(self.effects, vals)]
        return apply_effects(self.system, kc, mc, state, active)

    def dcoefficients(self, x, state: StateInfo) -> list[tuple[dict, dict]]:
        """Derivatives of the coefficients with respect to each component of ``x`` (central FD)."""
        x = np.asarray(x, float)
        out = []
        for j in range(self.n_params):
            h = 1e-6 if j < self.p else self.slots[j - self.p][1].fd_step(x[j])
            xp, xm = x.copy(), x.copy()
            xp[j] += h
            xm[j] -= h
            kp, mp = self.coefficients(xp, state)
            km, mm = self.coefficients(xm, state)
            dk = {k: (kp.get(k, 0.0) - km.get(k, 0.0)) / (2 * h) for k in sorted(set(kp) | set(km))}
            dm = {k: (mp.get(k, 0.0) - mm.get(k, 0.0)) / (2 * h) for k in sorted(set(mp) | set(mm))}
            out.append(({k: v for k, v in dk.items() if v != 0.0}, {k: v for k, v in dm.items() if v != 0.0}))
        return out

    def extended(self, spec: EffectSpec) -> "Variant":
        """This variant plus one more effect (its parameters appended at the end of ``x``)."""
        return Variant(self.system, self.settings, self.effects + [spec], theta_fixed=self.theta_fixed)
