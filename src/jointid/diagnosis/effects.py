"""Library of candidate physical effects: named, parameterised modifications of the affine FE model.

The diagnosis (``jointid.diagnosis.loop``) asks which of these effects the calibrated model lacks.  Each
effect changes only the *coefficients* of existing terms of :class:`jointid.fe.fem.Model` (or, for the
base support, replaces the clamped bottom by springs; the system of terms is
:mod:`jointid.diagnosis.terms`), so every variant stays affine:

    K(x, state) = K0 + sum_a g_a(x, state) K_a,      M(x) = M0 + sum_b h_b(x) M_b

and modal sensitivities are exact (``dlambda = phi^T (dK - lambda dM) phi``).

Effects (parameters in the config units; ``null`` = value at which the effect is absent)
------------------------------------------------------------------------------------------
``em_preload``        beta [-], null 0, range 0..1.  Pressure-dependent joint law k'' = alpha p^beta
                      (Yoshimura; docs/effects.md): every joint layer of carriage c is scaled by
                      ``((F_c + P) / (F_c,0 + P))^beta``, F_c the carriage load from the statics load
                      share of the motor attraction + carried weight (``jointid.response.emforce.carriage_loads_N``),
                      F_c,0 the same without motor force, P the block preload.  alpha is tied to the
                      calibrated joint stiffness at the weight-only pressure, so the power-off state
                      is the baseline.  Options: ``preload_N`` (0), ``force_x_m``, ``force_z_m``
                      (point of action of the attraction relative to the table centre, 0),
                      ``carried_mass_kg`` (default: table + carriages + motors from the model),
                      ``directions`` (spring directions following the law, default [x, y]: the
                      contact directions; the feed direction Z of a guide is held by the servo or
                      brake, not by contact pressure — add z for a sliding joint that is).
``added_mass_table``  mass_kg, null 0, range 0..30 kg: mass spread over the table top (fixture,
                      workpiece, accelerometers).
``added_mass_edge``   mass_kg, null 0, range 0..15 kg: mass on the table's +X side face (cable
                      chain, encoder read head).
``rail_fixing``       k_railfix_N_per_m3, null inf (bonded), range 1e10..inf: compliance of the
                      bolted rail-to-base interface, per unit area, all directions, in series with
                      the bonded layer.
``base_support``      k_foundation_N_per_m3, null inf (clamped), range 1e8..inf: the base rests on an
                      elastic foundation (levelling elements, floor) over its bottom face instead of
                      being clamped; per unit area, all directions.  Needs ``rig.support.kind:
                      clamped``.
``feed_stiffness``    k_feed_extra_N_per_m3, null 0, range 0..2e11: extra feed-direction (Z)
                      stiffness per area at the carriage joints (servo position loop or brake
                      holding the table), on the rail-top and flank layers.  Collinear with an
                      identified ``k_feed`` parameter (the diagnosis reports it as such).

Enabling effects in ``config.yaml``::

    effects:
      em_preload: {beta: 0.2, fit: true, preload_N: 0.0}
      added_mass_edge: {mass_kg: 1.5, fit: false}

``fit`` (default true) lets the diagnosis calibrate the effect's parameters together with the joint
parameters, starting at the given values; ``fit: false`` keeps them fixed.
"""

from __future__ import annotations

import difflib
import math
import warnings
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Callable

import numpy as np

from jointid.errors import ConfigError, ModelError
from jointid.response.emforce import carriage_loads_N

if TYPE_CHECKING:
    from jointid.diagnosis.terms import StateInfo, System
# jointid.diagnosis.terms (and with it the FE model, scipy and pandas) is imported where it is used: the
# Snakefile checks every hypothesis's effects with this registry at each Snakemake call.

__all__ = ["EFFECTS", "Effect", "Param", "Enabled", "enabled_effects", "check_hypothesis_effects", "apply_effects",
           "effect_table", "pressure_ratio"]

G = 9.81


# ------------------------------------------------------------------ effect definitions
@dataclass(frozen=True)
class Param:
    """One parameter of an effect.

    ``kind`` sets the dimensionless test variable ``t`` used by the diagnosis (0 = effect absent):
    ``linear``: ``t = (value - null) / nominal``; ``compliance`` (null = inf, a stiffness in series
    with a bonded layer): ``t = nominal / value``.
    """

    name: str
    unit: str
    null: float
    lower: float
    upper: float
    nominal: float
    kind: str
    description: str

    def to_t(self, value: float) -> float:
        """Test variable ``t`` of the physical ``value``."""
        if self.kind == "compliance":
            return 0.0 if math.isinf(value) else self.nominal / value
        return (value - self.null) / self.nominal

    def from_t(self, t: float) -> float:
        """Physical value of the test variable ``t`` (a tiny negative ``t`` of a compliance gives a
        negative stiffness, i.e. a slightly stiffer than bonded layer: used by finite differences)."""
        if self.kind == "compliance":
            return math.inf if t == 0 else self.nominal / t
        return self.null + t * self.nominal

    def fd_step(self, t: float) -> float:
        """Finite-difference step in ``t`` for coefficient derivatives."""
        if self.kind == "compliance":
            # keep the series compliance t / nominal far below the bonded one near t = 0
            from jointid.diagnosis.terms import BONDED_N_PER_M3  # noqa: PLC0415 (the registry loads light: see the top)
            return max(1e-6 * abs(t), 1e-4 * self.nominal / BONDED_N_PER_M3)
        return 1e-6 * max(abs(t), 1.0)

    def t_near_null(self, offset: float = 1e-4) -> float:
        """Test variable of the effect at its null (inside the bounds, an infinite upper bound taken as
        1e6), moved ``offset`` times the span towards the effect: the start of a fit that continues
        from the model without the effect."""
        lo, hi = self.t_bounds
        hi = hi if math.isfinite(hi) else 1e6
        return float(np.clip(self.to_t(self.null), lo, hi)) + offset * (hi - lo)

    @property
    def t_bounds(self) -> tuple[float, float]:
        """Bounds of ``t`` (from the physical range), low first."""
        a, b = self.to_t(self.lower), self.to_t(self.upper)
        return (min(a, b), max(a, b))


@dataclass(frozen=True)
class Effect:
    """A named, documented, parameterised modification of the model.

    ``apply(system, kc, mc, state, values, options)`` modifies the coefficient dicts in place;
    ``values`` maps parameter names to physical values.  ``requires(system, settings, states, options)``
    returns None or a sentence saying why the effect cannot act here.
    """

    name: str
    title: str
    description: str
    params: tuple
    options: dict
    apply: Callable
    requires: Callable | None = None

    def param(self, name: str) -> Param:
        """The parameter called ``name``."""
        return next(p for p in self.params if p.name == name)

    def null_values(self) -> dict:
        """Parameter values at which the effect is absent."""
        return {p.name: p.null for p in self.params}


def _carriage_loads(xz: np.ndarray, m: float, force: float, fx_m: float, fz_m: float) -> np.ndarray:
    """Normal load of each carriage at ``xz`` (m) under the weight of ``m`` kg and ``force`` N (its
    lever arms ``fx_m``, ``fz_m``)."""
    w = force + m * G
    lx = force * fx_m / w if w > 0 else 0.0
    lz = force * fz_m / w if w > 0 else 0.0
    if len(xz) < 3 or np.linalg.matrix_rank(np.column_stack([np.ones(len(xz)), xz])) < 3:
        # one carriage, or carriages on one line: the plane of settlement is not determined by
        # them; the load is shared equally (exact for one carriage, and for a load between two)
        return np.full(len(xz), w / len(xz))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return carriage_loads_N(force, m, xz[:, 0], xz[:, 1], load_x_m=lx, load_z_m=lz)


@lru_cache(maxsize=256)
def _loaded_and_weight(xz: tuple, m: float, force: float, pre: float, fx_m: float, fz_m: float) -> tuple:
    """Carriage loads (N) with ``force`` and with the weight alone, each plus the preload ``pre``:
    the same numbers at every fit of a state, so computed once (a fit asks thousands of times)."""
    xz_m = np.array(xz, dtype=float).reshape(-1, 2)
    f = _carriage_loads(xz_m, m, force, fx_m, fz_m) + pre
    f0 = _carriage_loads(xz_m, m, 0.0, fx_m, fz_m) + pre
    f.flags.writeable = f0.flags.writeable = False
    return f, f0


def pressure_ratio(system: System, state: StateInfo, opts: dict) -> np.ndarray:
    """Contact-pressure ratio of each carriage, loaded state over weight only, ``(n_carriages,)``."""
    m = opts.get("carried_mass_kg") or system.carried_mass_kg
    xz = tuple(np.asarray(system.carriage_xz_m, dtype=float).ravel().tolist())
    f, f0 = _loaded_and_weight(xz, float(m), float(state.em_force_N), float(opts.get("preload_N", 0.0)),
                               float(opts.get("force_x_m", 0.0)), float(opts.get("force_z_m", 0.0)))
    if np.any(f <= 0) or np.any(f0 <= 0):
        raise ModelError(f"effects.em_preload: a carriage lifts off in state {state.name} (loads "
                         f"{np.round(f, 1).tolist()} N) — the law k = alpha p^beta needs contact; "
                         "give preload_N or check force_x_m / force_z_m")
    return f / f0


def _apply_em(system, kc, mc, state, values, opts):
    beta = values["beta"]
    if beta == 0.0 or state.em_force_N == 0.0:
        return
    from jointid.diagnosis.terms import term_component  # noqa: PLC0415
    scale = pressure_ratio(system, state, opts) ** beta
    dirs = contact_directions(system, opts)
    for name in list(kc):
        if "@" in name and term_component(name) in dirs:
            kc[name] *= float(scale[int(name.split("@")[1])])


MESH_CONTACT = ("normal", "lateral", "tangential")
"""Components of a mesh file's joint layers that follow the contact pressure by default."""


def contact_directions(system: System, opts: dict) -> set:
    """Layer components scaled by the pressure law: ``opts['directions']``; its default (x, y, the
    rig's contact directions) means the normal and in-plane components of a mesh file's layers
    except the feed."""
    dirs = set(opts.get("directions") or ("x", "y"))
    if system.model.meta.get("kind") == "mesh" and dirs == {"x", "y"}:
        return set(MESH_CONTACT)
    return dirs


def _apply_mass(term):
    def apply(system, kc, mc, state, values, opts):
        if values["mass_kg"] != 0.0:
            mc[term] = mc.get(term, 0.0) + values["mass_kg"]
    return apply


def _series(term, pname):
    def apply(system, kc, mc, state, values, opts):
        from jointid.diagnosis.terms import BONDED_N_PER_M3  # noqa: PLC0415
        k = values[pname]
        if math.isinf(k):
            return
        kc[term] = 1.0 / (1.0 / kc.get(term, BONDED_N_PER_M3) + 1.0 / k)
    return apply


def _apply_feed(system, kc, mc, state, values, opts):
    k = values["k_feed_extra_N_per_m3"]
    if k == 0.0:
        return
    for name in _feed_terms(system):
        kc[name] = kc.get(name, 0.0) + k


def _feed_terms(system) -> list[str]:
    """Per-carriage layer terms in the feed direction (the rig's z, a mesh layer's feed component)."""
    from jointid.diagnosis.terms import term_component  # noqa: PLC0415
    return [n for n in system.stiffness if "@" in n and term_component(n) in ("z", "feed")]


def _needs_feed(system, settings, states, opts):
    if not _feed_terms(system):
        return "no joint layer has a feed (z) component to stiffen"
    return None


def _needs_term(term, where):
    def requires(system, settings, states, opts):
        if term not in system.stiffness and term not in system.mass:
            return f"the model has no {term} term ({where})"
        return None
    return requires


def _needs_two_forces(system, settings, states, opts):
    forces = {round(float(s.em_force_N), 6) for s in states}
    if len(forces) < 2:
        return ("needs states with different em_force_N (one force level only: the law cannot be "
                "told from the joint stiffness itself)")
    return None


def _needs_clamped(system, settings, states, opts):
    if system.support != "clamped":
        return f"applies to a clamped base (rig.support.kind is {system.support})"
    return None


EFFECTS: dict[str, Effect] = {
    "em_preload": Effect(
        name="em_preload", title="electromagnetic preload of the joints",
        description=("Motor attraction raises the carriage contact pressure; joint stiffness per area "
                     "follows k'' = alpha p^beta with p from the statics load share per carriage."),
        params=(Param("beta", "-", 0.0, 0.0, 1.0, 1.0, "linear",
                      "exponent of the pressure law k'' = alpha p^beta (Yoshimura: 0.3-0.8 for "
                      "sliding joints; ~0.1 or less for preloaded rolling blocks)"),),
        options={"preload_N": 0.0, "force_x_m": 0.0, "force_z_m": 0.0, "carried_mass_kg": None,
                 "directions": ["x", "y"]},
        apply=_apply_em, requires=_needs_two_forces),
    "added_mass_table": Effect(
        name="added_mass_table", title="added mass on the table top",
        description="Fixture, workpiece or sensors spread over the table top.",
        params=(Param("mass_kg", "kg", 0.0, 0.0, 30.0, 5.0, "linear", "added mass"),),
        options={}, apply=_apply_mass("M_table_top"),
        requires=_needs_term("M_table_top", "on a mesh file: a mass named table_top in model.masses")),
    "added_mass_edge": Effect(
        name="added_mass_edge", title="added mass on the table edge",
        description="Cable chain or encoder read head on the table's +X side face.",
        params=(Param("mass_kg", "kg", 0.0, 0.0, 15.0, 2.0, "linear", "added mass"),),
        options={}, apply=_apply_mass("M_table_edge"),
        requires=_needs_term("M_table_edge", "on a mesh file: a mass named table_edge in model.masses")),
    "rail_fixing": Effect(
        name="rail_fixing", title="compliant rail fixing",
        description="Bolted rail-to-base interface compliance per area (all directions).",
        params=(Param("k_railfix_N_per_m3", "N/m^3", math.inf, 1.0e10, math.inf, 1.0e12, "compliance",
                      "rail-to-base interface stiffness per area"),),
        options={}, apply=_series("K_railfix", "k_railfix_N_per_m3"),
        requires=_needs_term("K_railfix", "the rig's rail fixing layer")),
    "base_support": Effect(
        name="base_support", title="elastic base support",
        description="The base rests on an elastic foundation over its bottom face instead of a clamp.",
        params=(Param("k_foundation_N_per_m3", "N/m^3", math.inf, 1.0e8, math.inf, 1.0e10, "compliance",
                      "foundation stiffness per area of the base bottom, all directions"),),
        options={}, apply=_series("K_foundation", "k_foundation_N_per_m3"), requires=_needs_clamped),
    "feed_stiffness": Effect(
        name="feed_stiffness", title="feed-direction stiffness (servo or brake)",
        description="Extra Z stiffness per area at the carriage joints (position loop, brake).",
        params=(Param("k_feed_extra_N_per_m3", "N/m^3", 0.0, 0.0, 2.0e11, 1.0e10, "linear",
                      "extra feed-direction stiffness per area on the rail-top and flank layers"),),
        options={}, apply=_apply_feed, requires=_needs_feed),
}


# ------------------------------------------------------------------ config and application
DIRECTIONS = ("x", "y", "z", "normal", "feed", "lateral", "tangential", "all")
"""Layer directions or components an effect's ``directions`` option may name."""

@dataclass
class Enabled:
    """An effect switched on in the config: its physical parameter values, options and fit flag."""

    effect: Effect
    values: dict
    options: dict
    fit: bool = True
    configured: tuple = ()  # the parameters given a value in the config (the others start at their default)


def enabled_effects(effects: dict | None) -> list[Enabled]:
    """Parse the ``effects`` config section (name -> {param values, options, fit}).

    Raises
    ------
    ConfigError
        One line per unknown effect, unknown key or out-of-range value.
    """
    problems, out = [], []
    for name, spec in (effects or {}).items():
        if name not in EFFECTS:
            close = difflib.get_close_matches(name, list(EFFECTS), n=1)
            hint = f"did you mean {close[0]!r}? " if close else ""
            problems.append(f"config.yaml: effects.{name}: unknown effect — {hint}use one of "
                            f"{', '.join(EFFECTS)}")
            continue
        eff = EFFECTS[name]
        spec = dict(spec or {})
        fit = spec.pop("fit", True)
        if not isinstance(fit, bool):
            problems.append(f"config.yaml: effects.{name}.fit: {fit!r} is not true/false — write fit: true "
                            "or fit: false")
        values, opts = {}, dict(eff.options)
        for key, v in spec.items():
            if key in {p.name for p in eff.params}:
                p = eff.param(key)
                try:
                    v = float(v)
                except (TypeError, ValueError):
                    problems.append(f"config.yaml: effects.{name}.{key}: {v!r} is not a number — give "
                                    f"{p.description} in {p.unit}")
                    continue
                if not (p.lower <= v <= p.upper):
                    problems.append(f"config.yaml: effects.{name}.{key}: {v:g} is outside the plausible "
                                    f"range {p.lower:g}..{p.upper:g} {p.unit} — give a value inside it")
                values[key] = v
            elif key == "directions":
                if not isinstance(v, list) or not v or any(d not in DIRECTIONS for d in v):
                    problems.append(f"config.yaml: effects.{name}.directions: {v!r} is not a list of "
                                    f"{', '.join(DIRECTIONS)} — write e.g. directions: [x, y] (rig) or "
                                    "[normal, lateral] (mesh file)")
                opts[key] = v
            elif key in eff.options:
                opts[key] = v
            else:
                allowed = [p.name for p in eff.params] + list(eff.options) + ["fit"]
                close = difflib.get_close_matches(key, allowed, n=1)
                hint = f"did you mean {close[0]!r}? " if close else ""
                problems.append(f"config.yaml: effects.{name}.{key}: unknown key — {hint}allowed keys: "
                                f"{', '.join(allowed)}")
        # start values: the null of a linear parameter, the nominal of a compliance, unless configured
        start = {p.name: p.nominal if p.kind == "compliance" else p.null for p in eff.params}
        out.append(Enabled(eff, {**start, **values}, opts, bool(fit), tuple(values)))
    if problems:
        raise ConfigError(problems)
    return out


def check_hypothesis_effects(where: str, effects: dict | None) -> None:
    """Raise :class:`ConfigError` when the ``effects`` of a hypothesis (``where``: ``config.yaml:
    hypotheses.<name>``) do not parse (:func:`jointid.diagnosis.effects.enabled_effects`), its lines naming the
    hypothesis, not the run's effects section (the check :func:`jointid.config.hypotheses.hypothesis_config`
    is handed)."""
    try:
        enabled_effects(effects)
    except ConfigError as exc:  # name the hypothesis, not the run's effects section
        raise ConfigError([str(line).replace("config.yaml: effects.", f"{where}.effects.")
                           for line in exc.problems]) from None


def apply_effects(system: System, kc: dict, mc: dict, state: StateInfo,
                  active: list[tuple[Effect, dict, dict]]) -> tuple[dict, dict]:
    """Coefficients with the ``active`` effects ``[(effect, values, options), ...]`` applied.

    Effects act in the given order on copies of ``kc``/``mc`` (returned).
    """
    kc, mc = dict(kc), dict(mc)
    for eff, values, opts in active:
        eff.apply(system, kc, mc, state, values, opts)
    return kc, mc


def effect_table() -> list[dict]:
    """One row per effect parameter (for docs and reports): effect, parameter, unit, null, range."""
    rows = []
    for e in EFFECTS.values():
        for p in e.params:
            rows.append({"effect": e.name, "title": e.title, "parameter": p.name, "unit": p.unit,
                         "null": p.null, "lower": p.lower, "upper": p.upper,
                         "description": p.description})
    return rows
