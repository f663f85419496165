"""The reconstruction hypotheses' configurations (``hypotheses:``), and the options their stages read.

A hypothesis is config overrides plus fixed joint parameters and library effects
(docs/reconstruction.md, "Hypotheses"); :func:`hypothesis_config` makes its configuration from the run's,
:func:`needs_own_model` says whether it needs a model of its own.  Its job (:class:`HypothesisJob`) and the
ranking (:class:`RankingOptions`) are built from the configuration once, at the edge (the rule scripts);
the fits (:mod:`jointid.reconstruction.hypotheses`) take them, not the dict.  The effects a hypothesis names
are checked by the diagnosis's own parser: the caller hands its check in (``check_effects``,
:func:`jointid.diagnosis.effects.check_hypothesis_effects`).
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from jointid.config.load import load_config
from jointid.config.options import given
from jointid.config.schema import field_default
from jointid.config.typed import ModelSpec, read_only
from jointid.config.typed_diagnosis import DiagnosisSettings
from jointid.errors import ConfigError
from jointid.yamlio import deep_merge

__all__ = ["COEFFICIENT_KEYS", "HYPOTHESIS_KEYS", "MODEL_SECTIONS", "HypothesisJob", "LinkedLaw", "ProposalOptions",
           "RankingOptions", "check_hypotheses", "cost_rank", "hypothesis_config", "hypothesis_names",
           "needs_own_model"]

HYPOTHESIS_KEYS = ("description", "overrides", "fixed", "effects")
MODEL_SECTIONS = ("materials", "rig", "model", "mesh")
"""Sections the FE model is built from.  An override of them builds the hypothesis's own model
unless it changes coefficients of the run's model only (:func:`needs_own_model`)."""
COEFFICIENT_KEYS = (("rig", "motors", "mass_each_kg"), ("rig", "motors", "count"),
                    ("rig", "rails", "fixing_stiffness_N_per_m3"), ("rig", "support", "k_mount_N_per_m"))
"""Rig keys that are coefficients of the run's model (``M_motor``, ``K_railfix``, ``K_mount``);
materials are too (``K_solid_<part>``, ``M_solid_<part>``, :mod:`jointid.fe.model`; a part of another
Poisson's ratio adds ``K_lambda_<part>``, :mod:`jointid.fe.lame`)."""

EffectsCheck = Callable[[str, "Mapping | None"], None]
"""``check(where, effects)``: raises :class:`ConfigError` naming ``where`` for a bad ``effects`` section."""


def _classes(values) -> tuple[float, ...]:
    """Preload classes (N) as floats; none: one class at 0 N."""
    return tuple(float(p) for p in values) or (0.0,)


@dataclass(frozen=True)
class LinkedLaw:
    """The linked two-state law of the ``linked`` config section (defaults: the schema's)."""

    preload_classes_N: tuple = field_default("linked.preload_classes_N", _classes)
    directions: tuple = field_default("linked.directions", tuple)
    beta_start: float = field_default("linked.beta_start", float)

    @classmethod
    def from_config(cls, cfg: Mapping) -> LinkedLaw:
        """The law of ``cfg['linked']`` (the schema's defaults where absent)."""
        sec = dict(cfg.get("linked") or {})
        return cls(_classes(given(sec, "preload_classes_N", "linked.preload_classes_N")),
                   tuple(given(sec, "directions", "linked.directions")),
                   float(given(sec, "beta_start", "linked.beta_start")))


@dataclass(frozen=True)
class ProposalOptions:
    """The assumed uncertainties of the candidate measurements and the draws (config ``next_measurement``;
    defaults: the schema's), and the admissible delta QAICc."""

    weight_uncertainty_pct: float = field_default("next_measurement.weight_uncertainty_pct", float)
    static_stiffness_uncertainty_pct: float = field_default("next_measurement.static_stiffness_uncertainty_pct", float)
    shape_uncertainty_pct: float = field_default("next_measurement.shape_uncertainty_pct", float)
    n_draws: int = field_default("next_measurement.n_draws", int)
    seed: int = field_default("next_measurement.seed", int)
    target: str = field_default("next_measurement.target", str)
    delta: float = 4.0

    @classmethod
    def from_config(cls, cfg: Mapping | None, delta: float = 4.0) -> ProposalOptions:
        """The options of ``cfg['next_measurement']`` (the schema's defaults where absent)."""
        sec = dict((cfg or {}).get("next_measurement") or {})
        key = "next_measurement."
        return cls(float(given(sec, "weight_uncertainty_pct", key + "weight_uncertainty_pct")),
                   float(given(sec, "static_stiffness_uncertainty_pct", key + "static_stiffness_uncertainty_pct")),
                   float(given(sec, "shape_uncertainty_pct", key + "shape_uncertainty_pct")),
                   int(given(sec, "n_draws", key + "n_draws")), int(given(sec, "seed", key + "seed")),
                   str(sec.get("target") or ""), float(delta))


def hypothesis_config(cfg: Mapping, name: str, hyp: Mapping, check_effects: EffectsCheck | None = None) -> dict:
    """The configuration of hypothesis ``name``: ``cfg`` with its overrides merged, its fixed joint
    parameters moved from ``joints.parameters`` to ``joints.fixed`` and its effects added to
    ``effects``.  Raise :class:`ConfigError` on an unknown key, a fixed name that is no joint
    parameter, or (with ``check_effects``) an effect its check refuses."""
    where = f"config.yaml: hypotheses.{name}"
    unknown = [k for k in hyp if k not in HYPOTHESIS_KEYS]
    if unknown:
        raise ConfigError([f"{where}.{k}: unknown key — allowed keys: {', '.join(HYPOTHESIS_KEYS)}" for k in unknown])
    out = deep_merge(copy.deepcopy(cfg), copy.deepcopy(hyp.get("overrides") or {}))
    joints = out["joints"]
    params = dict(joints["parameters"])
    fixed = dict(joints.get("fixed") or {})
    for k, v in (hyp.get("fixed") or {}).items():
        if k not in params and k not in fixed:
            raise ConfigError(f"{where}.fixed.{k}: not a joint parameter — use one of {', '.join(params)}")
        params.pop(k, None)
        fixed[k] = float(v)
    joints["parameters"], joints["fixed"] = params, fixed
    effects = dict(out.get("effects") or {})
    effects.update(copy.deepcopy(hyp.get("effects") or {}))
    out["effects"] = effects
    if check_effects is not None:
        check_effects(where, hyp.get("effects"))
    return out


def needs_own_model(hyp: Mapping, cfg: Mapping | None = None) -> bool:
    """Whether the hypothesis changes the FE model itself, not only coefficients of the run's model.

    With the run's configuration ``cfg``: whether its overrides change what a coefficient cannot —
    geometry (thickness, spacing, positions), the support kind, the mesh, a mesh file.  A part's
    material (``materials``, or another material: Young's modulus, density and Poisson's ratio, the
    last by the Lamé split of :mod:`jointid.fe.lame`), motor mass or count, rail-fixing or mount
    stiffness is a coefficient change of the run's model (:func:`jointid.fe.model.base_coefficients`).  Without
    ``cfg``: whether it overrides any of :data:`MODEL_SECTIONS` at all."""
    over = hyp.get("overrides") or {}
    if not any(k in MODEL_SECTIONS for k in over):
        return False
    if cfg is None:
        return True
    return _model_shape(cfg) != _model_shape(deep_merge(copy.deepcopy(cfg), copy.deepcopy(over)))


def _model_shape(cfg: Mapping) -> dict:
    """What of the model sections of ``cfg`` no coefficient can change: the sections without the
    materials, the parts' choice of material and :data:`COEFFICIENT_KEYS` (a mesh file's model: the
    sections as they are)."""
    shape = {k: copy.deepcopy(cfg.get(k)) for k in MODEL_SECTIONS}
    if (shape["model"] or {}).get("kind", "rig") == "mesh":
        return shape
    shape.pop("materials")
    rig = shape["rig"] or {}
    for section in ("base", "rails", "carriages", "table"):
        (rig.get(section) or {}).pop("material", None)
    for sec, sub, key in COEFFICIENT_KEYS:
        ((shape.get(sec) or {}).get(sub) or {}).pop(key, None)
    return shape


def hypothesis_names(cfg: Mapping) -> list[str]:
    """The configured hypotheses, in config order (an entry set to null in a later config file is
    switched off)."""
    return [n for n, h in (cfg.get("hypotheses") or {}).items() if h is not None]


def check_hypotheses(cfg: Mapping, check_effects: EffectsCheck | None = None) -> list[str]:
    """Every configured hypothesis's configuration built and (``check_effects``) its effects parsed, before
    any job runs; returns the names, raises :class:`ConfigError` with one line per problem of any of them."""
    names, problems = hypothesis_names(cfg), []
    for name in names:
        try:
            hypothesis_config(cfg, name, cfg["hypotheses"][name], check_effects)
        except ConfigError as exc:
            problems += exc.problems
    if problems:
        raise ConfigError(problems)
    return names


def cost_rank(cfg: Mapping, name: str) -> int:
    """0, 1 or 2: how much work hypothesis ``name`` makes beyond a coefficient change of the run's
    model (one for building its own model, one for fitting an effect's parameters, which grows the
    shared basis).  Rule ``hypothesis`` adds it to its priority, so that on few cores the longer jobs
    start first and the run ends on short ones."""
    hyp = cfg["hypotheses"][name] or {}
    return int(needs_own_model(hyp, cfg)) + int(bool(hyp.get("effects")))


@dataclass(frozen=True)
class HypothesisJob:
    """One hypothesis's fit (rule ``hypothesis``): its name and description, the diagnosis settings of its
    validated configuration, its linked law, whether it builds its own model (``own_model``: with the run's
    configuration; ``overrides_model``: whether it overrides a model section at all, for a model file of an
    older version) and the motor forces its overrides give (N, by state)."""

    name: str
    description: str
    settings: DiagnosisSettings
    law: LinkedLaw
    own_model: bool
    overrides_model: bool
    forces_N: Mapping[str, float]

    @classmethod
    def from_config(cls, cfg: Mapping, name: str, check_effects: EffectsCheck | None = None) -> HypothesisJob:
        """The job of hypothesis ``name`` of the run's configuration ``cfg`` (its configuration validated like
        config.yaml, its problems naming the hypothesis)."""
        hyp = dict((cfg.get("hypotheses") or {}).get(name) or {})
        if not hyp and name not in (cfg.get("hypotheses") or {}):
            raise ConfigError(f"config.yaml: hypotheses.{name}: no such hypothesis — the configured ones are "
                              f"{', '.join(cfg.get('hypotheses') or {}) or 'none'}")
        cfg_h = load_config(hypothesis_config(cfg, name, hyp, check_effects),
                            source=f"config.yaml (hypothesis {name})")
        forces = {s: float(v["em_force_N"]) for s, v in (((hyp.get("overrides") or {}).get("states")) or {}).items()
                  if isinstance(v, Mapping) and "em_force_N" in v}
        return cls(name, str(hyp.get("description", "")), DiagnosisSettings.from_config(cfg_h),
                   LinkedLaw.from_config(cfg_h), needs_own_model(hyp, cfg), needs_own_model(hyp), read_only(forces))


@dataclass(frozen=True)
class RankingOptions:
    """The ranking of the fitted hypotheses (rule ``hypotheses``): each hypothesis's model and the cell size (m)
    of the catalogue-style block test its linked fit gets (``carriage_tests``; empty without a configuration),
    and the next measurement's options."""

    carriage_tests: Mapping[str, tuple[ModelSpec, float]]
    proposal: ProposalOptions

    @classmethod
    def from_config(cls, cfg: Mapping | None, delta: float = 4.0) -> RankingOptions:
        """Sections ``materials, rig, model, joints, carriage_rigidity, hypotheses, next_measurement`` and keys
        ``mesh.element``, ``solver.backend``; ``delta``: the admissible delta QAICc."""
        tests = {}
        for name in hypothesis_names(cfg or {}):
            cfg_h = hypothesis_config(cfg, name, cfg["hypotheses"][name] or {})
            tests[name] = (ModelSpec.from_config(cfg_h), cfg_h["carriage_rigidity"]["cell_size_m"])
        return cls(tests, ProposalOptions.from_config(cfg, delta=delta))
