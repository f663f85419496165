"""What the diagnosis reads of a configuration, as one frozen object (:class:`DiagnosisSettings`).

Built once at the edge (the rule ``diagnose`` and its kin, the API's :class:`jointid.Study`, a synthetic
dataset's generator) by :meth:`DiagnosisSettings.from_config`, and handed to
:func:`jointid.diagnosis.terms.build_system`, :func:`jointid.diagnosis.variants.dataset_states`,
:class:`jointid.diagnosis.variants.Variant`, :class:`jointid.diagnosis.fitting.Diagnoser` and
:func:`jointid.diagnosis.loop.diagnose`, which take it instead of the config dict.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass, replace

from jointid.config.datasets import dataset_folder
from jointid.config.hashing import config_digest, config_hash, mesh_digest
from jointid.config.options import given
from jointid.config.typed import ModelSpec, TestSetup, read_only

__all__ = ["DiagnoseJob", "DiagnosisSettings", "FIT_CONTEXT_LEFT_OUT", "ResponseSetup"]

FIT_CONTEXT_LEFT_OUT = ("diagnosis", "dataset", "effects")
"""Sections the recorded fits do not depend on (:mod:`jointid.diagnosis.memo`): the loop's options, the
dataset, and the effects (those of a variant are part of the variant)."""


@dataclass(frozen=True)
class ResponseSetup:
    """The drive-point response a fitted hypothesis reports (``harmonic``): its Table 1 at the drive point and
    direction over the band (Hz; ``n_freq`` frequencies) at one modal damping ratio, and the predicted static
    stiffness over the hammer-tip patch (m).  ``damping_ratio``: ``harmonic.damping.damping_ratio``, the schema's
    default for the modal model where the configuration gives none (whatever the damping model)."""

    drive_point: str
    direction: str
    band_Hz: tuple[float, float]
    n_freq: int
    patch_diameter_m: float
    damping_ratio: float

    @classmethod
    def from_section(cls, h: Mapping | None) -> ResponseSetup:
        """The setup of a ``harmonic`` section (a key it lacks: the schema's default)."""
        h = h or {}
        return cls(str(given(h, "drive_point", "harmonic.drive_point")), given(h, "direction", "harmonic.direction"),
                   tuple(given(h, "band_Hz", "harmonic.band_Hz")), int(given(h, "n_freq", "harmonic.n_freq")),
                   float(given(h, "patch_diameter_m", "harmonic.patch_diameter_m")),
                   float(given(h.get("damping"), "damping_ratio", "harmonic.damping.damping_ratio")))


@dataclass(frozen=True)
class DiagnosisSettings:
    """The diagnosis's view of one configuration.

    ``model``: the FE model (:class:`~jointid.config.typed.ModelSpec`; ``model.joints`` are the fitted joint
    parameters and their bounds); ``test_setup``: the test a dataset gets without its own; ``min_freq_Hz``,
    ``shift_Hz``, ``backend``: the reduced solver's lowest tracked frequency (Hz), shift (Hz) and sparse
    backend (``solver``); ``frequency_uncertainty_pct``: the measured frequencies' default uncertainty
    (``identify``); ``em_force_N``: each configured state's motor force (N, where ``states`` gives it);
    ``diagnosis`` and ``effects``: copies of those sections as given (the loop's options over
    :func:`jointid.diagnosis.loop.default_options`, the effects enabled in the model); ``mesh_digest``:
    :func:`jointid.config.hashing.mesh_digest` of the mesh; ``fingerprint``: a digest of every section but
    :data:`FIT_CONTEXT_LEFT_OUT`, what the recorded fits depend on; ``response``: the drive-point response a
    fitted hypothesis reports (:class:`ResponseSetup`); ``datasets``: each configured state's dataset folder
    (:func:`jointid.config.datasets.dataset_folder`), in config order.
    """

    model: ModelSpec
    test_setup: TestSetup
    min_freq_Hz: float
    shift_Hz: float
    backend: str
    frequency_uncertainty_pct: float
    em_force_N: Mapping[str, float]
    diagnosis: Mapping
    effects: Mapping
    mesh_digest: str
    fingerprint: str
    response: ResponseSetup
    datasets: Mapping[str, str]

    @classmethod
    def from_config(cls, cfg: Mapping) -> DiagnosisSettings:
        """The settings of a validated configuration (a section it lacks: the schema's defaults)."""
        s, ident = cfg.get("solver") or {}, cfg.get("identify") or {}
        forces = {str(k): float(v["em_force_N"]) for k, v in (cfg.get("states") or {}).items()
                  if isinstance(v, Mapping) and "em_force_N" in v}
        return cls(ModelSpec.from_config(cfg), TestSetup.from_config(cfg),
                   float(given(s, "min_freq_Hz", "solver.min_freq_Hz")), float(given(s, "shift_Hz", "solver.shift_Hz")),
                   given(s, "backend", "solver.backend"),
                   float(given(ident, "frequency_uncertainty_pct", "identify.frequency_uncertainty_pct")),
                   read_only(forces), copy.deepcopy(dict(cfg.get("diagnosis") or {})),
                   copy.deepcopy(dict(cfg.get("effects") or {})), mesh_digest(cfg),
                   config_digest({k: v for k, v in cfg.items() if k not in FIT_CONTEXT_LEFT_OUT}),
                   ResponseSetup.from_section(cfg.get("harmonic")),
                   read_only({str(s): dataset_folder(cfg, s) for s in cfg.get("states") or {}}))

    @property
    def directions(self) -> dict[str, str]:
        """Each fitted joint parameter's direction (``joints.parameters.<name>.direction``)."""
        return {p.name: p.direction for p in self.model.joints.parameters}

    @property
    def mesh_error_halve(self) -> tuple[str, ...] | None:
        """The cell classes the mesh error halves (``diagnosis.mesh_error_halve``; None or empty: not given)."""
        halve = self.diagnosis.get("mesh_error_halve")
        return tuple(halve) if halve else None

    @property
    def shape_residuals(self) -> bool:
        """Whether the fits take the measured shapes' rows (``diagnosis.shape_residuals``)."""
        return bool(given(self.diagnosis, "shape_residuals", "diagnosis.shape_residuals"))

    @property
    def mesh_error(self) -> bool:
        """Whether the budget takes the mesh's correction and known error (``diagnosis.mesh_error``)."""
        return bool(given(self.diagnosis, "mesh_error", "diagnosis.mesh_error"))

    def with_effects(self, effects: Mapping | None) -> DiagnosisSettings:
        """These settings with the ``effects`` section ``effects`` (None or empty: none enabled)."""
        return replace(self, effects=copy.deepcopy(dict(effects or {})))


@dataclass(frozen=True)
class DiagnoseJob:
    """One diagnosis of a dataset (rules ``diagnose`` and ``current``, ``python -m jointid.diagnosis``): the
    settings, the dataset's states to diagnose (``dataset.states``; None: all), whether the reduced basis and
    the fits are kept for the next run (``diagnosis.reuse_subspace``) and the configuration's hash (without
    ``dataset``) that the results record."""

    settings: DiagnosisSettings
    states: tuple[str, ...] | None
    reuse_subspace: bool
    config_hash: str

    @classmethod
    def from_config(cls, cfg: Mapping) -> DiagnoseJob:
        """The job of a configuration with its ``dataset`` entry (``path``, ``states``)."""
        states = (cfg.get("dataset") or {}).get("states")
        return cls(DiagnosisSettings.from_config(cfg), None if not states else tuple(states),
                   bool(given(cfg.get("diagnosis"), "reuse_subspace", "diagnosis.reuse_subspace")),
                   config_hash({k: v for k, v in cfg.items() if k != "dataset"}))
