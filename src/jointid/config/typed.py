"""The validated configuration as typed, frozen objects: parsed once, read by the domain layers.

:meth:`Settings.from_config` turns the output of :func:`jointid.config.load_config` into the
objects below.  The layers ``fe``, ``identification``, ``response`` and ``correlate`` take these
objects or plain numbers, never the whole configuration dict.  Field names carry their units, as the
YAML keys do.  Values are kept as the configuration gives them (no conversion), so that every number
computed from them stays the same.

* :class:`ModelSpec` - what the FE model is built from and solved with: the materials, the joints,
  the mesh options, the solver options, and the rig (:class:`RigModel`) or the user's mesh file
  (:class:`jointid.config.typed_mesh.MeshFileModel`);
* :class:`TestSetup` - the test a dataset gets when its conditions give none (drive point, band) and
  the visibility threshold;
* :class:`Damping` - the harmonic analysis's damping model;
* :class:`Settings` - all of them, built once.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from jointid.config.schema import field_default, given
from jointid.config.typed_mesh import MeshFileModel, read_only

__all__ = ["Damping", "JointParameter", "Joints", "Material", "MeshOptions", "ModelSpec", "RigModel", "Settings",
           "SolverOptions", "TestSetup", "read_only"]


@dataclass(frozen=True)
class Material:
    """An isotropic elastic material (``materials.<name>``)."""

    youngs_modulus_Pa: float
    poisson_ratio: float
    density_kg_per_m3: float

    @classmethod
    def from_section(cls, section: Mapping) -> Material:
        """The material of one ``materials.<name>`` section."""
        return cls(section["youngs_modulus_Pa"], section["poisson_ratio"], section["density_kg_per_m3"])


@dataclass(frozen=True)
class JointParameter:
    """One identified joint stiffness per area (``joints.parameters.<name>``), with its log-uniform bounds."""

    name: str
    direction: str
    lower_N_per_m3: float
    upper_N_per_m3: float

    @property
    def default_N_per_m3(self) -> float:
        """The geometric mean of the bounds, N/m^3: the value where none is given."""
        return float(np.sqrt(self.lower_N_per_m3 * self.upper_N_per_m3))


@dataclass(frozen=True)
class Joints:
    """The carriage-rail joints (``joints``): identified parameters in config order, fixed ones, faces."""

    parameters: tuple[JointParameter, ...]
    fixed_N_per_m3: Mapping[str, float]
    lateral_face: str = "flanks"

    @classmethod
    def from_section(cls, section: Mapping) -> Joints:
        """The joints of a validated ``joints`` section."""
        params = tuple(JointParameter(name, s["direction"], s["lower"], s["upper"])
                       for name, s in section.get("parameters", {}).items())
        return cls(params, read_only(dict(section.get("fixed", {}))), section.get("lateral_face", "flanks"))

    @property
    def names(self) -> list[str]:
        """The identified parameters' names, in config order."""
        return [p.name for p in self.parameters]

    @property
    def lower_N_per_m3(self) -> np.ndarray:
        """Lower bounds of the identified parameters, N/m^3 ``(n_params,)``."""
        return np.array([p.lower_N_per_m3 for p in self.parameters], float)

    @property
    def upper_N_per_m3(self) -> np.ndarray:
        """Upper bounds of the identified parameters, N/m^3 ``(n_params,)``."""
        return np.array([p.upper_N_per_m3 for p in self.parameters], float)

    def defaults_N_per_m3(self) -> dict[str, float]:
        """Every parameter's value where none is given, N/m^3: the geometric mean of the bounds for
        identified ones, the configured value for fixed ones."""
        values = {p.name: p.default_N_per_m3 for p in self.parameters}
        values.update({k: float(v) for k, v in self.fixed_N_per_m3.items()})
        return values


@dataclass(frozen=True)
class MeshOptions:
    """The rig's structured hexahedral mesh (``mesh``; defaults: the schema's)."""

    element: str = field_default("mesh.element")
    max_cell_size_m: float = field_default("mesh.max_cell_size_m")
    height_cell_fraction: float = field_default("mesh.height_cell_fraction")
    joint_cell_fraction: float = field_default("mesh.joint_cell_fraction")
    refine: int = field_default("mesh.refine")
    edge_refine_levels: int = field_default("mesh.edge_refine_levels")
    extrapolate_edges: bool = field_default("mesh.extrapolate_edges")
    edge_ratio: float | None = field_default("mesh.edge_ratio")

    @property
    def edge_extra_levels(self) -> tuple[int, ...]:
        """The edge levels beyond this mesh that the extrapolation solves: one with a given
        ``edge_ratio``, two (Aitken, the ratio estimated per mode) without."""
        return (1,) if self.edge_ratio else (1, 2)

    @classmethod
    def from_section(cls, section: Mapping) -> MeshOptions:
        """The options of a ``mesh`` section; keys it does not give take the schema's defaults."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in section.items() if k in names})


@dataclass(frozen=True)
class SolverOptions:
    """The shift-invert eigen solver (``solver``); a key the section does not give is None (a workflow
    rule gets only the keys it hashes, e.g. ``solver.backend`` alone)."""

    n_modes: int | None = None
    shift_Hz: float | None = None
    backend: str | None = None
    min_freq_Hz: float | None = None
    method: str = field_default("solver.method")
    rom_tolerance: float = field_default("solver.rom_tolerance")

    @classmethod
    def from_section(cls, section: Mapping) -> SolverOptions:
        """The options of a validated ``solver`` section (``method`` and ``rom_tolerance`` default to the
        schema's)."""
        return cls(section.get("n_modes"), section.get("shift_Hz"), section.get("backend"), section.get("min_freq_Hz"),
                   **{k: section[k] for k in ("method", "rom_tolerance") if k in section})


PART_SECTIONS = {"base": "base", "rail": "rails", "carriage": "carriages", "table": "table"}
"""The ``rig`` section naming each part's material."""


@dataclass(frozen=True)
class RigModel:
    """The parametric test rig (``rig``).

    ``geometry`` is the whole ``rig`` section, read-only, for :mod:`jointid.geometry` (``build_rig``,
    ``measuring_points``); the fields the FE layer reads are typed beside it.
    ``rail_fixing_N_per_m3`` is None for a bonded rail fixing.
    """

    geometry: Mapping[str, Any]
    support_kind: str
    k_mount_N_per_m: float | None
    rail_fixing_N_per_m3: float | None
    motor_count: int
    motor_mass_each_kg: float
    part_materials: Mapping[str, str]  # part (base, rail, carriage, table) -> material name

    @classmethod
    def from_section(cls, section: Mapping) -> RigModel:
        """The rig of a validated ``rig`` section."""
        geometry = read_only(section)
        return cls(geometry, geometry["support"]["kind"], geometry["support"].get("k_mount_N_per_m"),
                   geometry["rails"].get("fixing_stiffness_N_per_m3"), geometry["motors"]["count"],
                   geometry["motors"]["mass_each_kg"],
                   read_only({part: geometry[s]["material"] for part, s in PART_SECTIONS.items()}))

    @property
    def motor_mass_kg(self) -> float:
        """The motor primaries' mass on the table, kg (count x mass each, as the configuration gives them)."""
        return self.motor_count * self.motor_mass_each_kg


@dataclass(frozen=True)
class ModelSpec:
    """What the FE model is built from and solved with.

    Built by :meth:`from_config` from the sections a configuration has: a workflow rule gets only the
    sections it hashes (the Snakefile's ``CONFIG`` of each stage), so a part whose section is missing
    is None (the materials: empty), and a function that needs it fails there.  ``mesh_file`` is the
    user's mesh file with ``model: {kind: mesh}``, else None.
    """

    materials: Mapping[str, Material]
    joints: Joints | None
    mesh: MeshOptions | None
    solver: SolverOptions | None
    rig: RigModel | None
    mesh_file: MeshFileModel | None = None

    @classmethod
    def from_config(cls, cfg: Mapping) -> ModelSpec:
        """The model of a validated configuration (sections materials, joints, mesh, solver, rig, model)."""
        model = cfg.get("model") or {}

        def part(key, build):
            return build(cfg[key]) if key in cfg else None

        return cls(materials=read_only({k: Material.from_section(m) for k, m in cfg.get("materials", {}).items()}),
                   joints=part("joints", Joints.from_section), mesh=part("mesh", MeshOptions.from_section),
                   solver=part("solver", SolverOptions.from_section), rig=part("rig", RigModel.from_section),
                   mesh_file=MeshFileModel.from_section(model) if model.get("kind", "rig") == "mesh" else None)

    @property
    def is_mesh_file(self) -> bool:
        """Whether the model is read from a mesh file (``model: {kind: mesh}``)."""
        return self.mesh_file is not None

    def with_edge_levels(self, extra: int) -> ModelSpec:
        """This model with ``extra`` more edge-refinement levels of the mesh (itself for none)."""
        if not extra:
            return self
        mesh = dataclasses.replace(self.mesh, edge_refine_levels=int(self.mesh.edge_refine_levels) + extra)
        return dataclasses.replace(self, mesh=mesh)

    def with_solver(self, **changes) -> ModelSpec:
        """This model with the solver options ``changes`` (e.g. ``n_modes=30``)."""
        return dataclasses.replace(self, solver=dataclasses.replace(self.solver, **changes))


@dataclass(frozen=True)
class TestSetup:
    """The test a dataset gets when its conditions give no ``test_setup``, and the visibility rule's threshold.

    ``drive_point``: the hammer's measuring point (``harmonic.drive_point``, hit in x, y and z);
    ``band_Hz``: the test band (``harmonic.band_Hz``); ``visible_threshold``: the share of the weakest
    paired mode's visibility above which a mode counts as seen (``identify.visible_threshold``; None:
    no visibility rule).
    """

    __test__ = False  # not a pytest test class

    drive_point: str = field_default("harmonic.drive_point")
    band_Hz: tuple[float, float] = field_default("harmonic.band_Hz", tuple)
    visible_threshold: float | None = field_default("identify.visible_threshold")

    @classmethod
    def from_config(cls, cfg: Mapping) -> TestSetup:
        """The test setup of a configuration (sections harmonic and identify; a key they lack: the schema's)."""
        harmonic, ident = cfg.get("harmonic", {}), cfg.get("identify", {})
        return cls(given(harmonic, "drive_point", "harmonic.drive_point"),
                   tuple(given(harmonic, "band_Hz", "harmonic.band_Hz")),
                   given(ident, "visible_threshold", "identify.visible_threshold"))


@dataclass(frozen=True)
class Damping:
    """The harmonic analysis's damping model (``harmonic.damping``, without Table 1's assumed range).

    ``model``: modal, rayleigh, joint or measured; ``damping_ratio`` (model modal, fraction of
    critical); ``alpha_per_s``, ``beta_s`` (model rayleigh, 1/s and s); ``joint_loss_factor_s``
    (model joint, s).  A parameter the configuration does not give is None.
    """

    model: str = "modal"
    damping_ratio: float | None = None
    alpha_per_s: float | None = None
    beta_s: float | None = None
    joint_loss_factor_s: float | None = None

    @classmethod
    def from_section(cls, section: Mapping | None) -> Damping:
        """The damping of a ``harmonic.damping`` section (None or empty: the defaults)."""
        d = dict(section or {})
        return cls(d.get("model", "modal"), d.get("damping_ratio"), d.get("alpha_per_s"), d.get("beta_s"),
                   d.get("joint_loss_factor_s"))


@dataclass(frozen=True)
class Settings:
    """The typed objects of one validated configuration, built once by :meth:`from_config`."""

    model: ModelSpec
    test_setup: TestSetup

    @classmethod
    def from_config(cls, cfg: Mapping) -> Settings:
        """All typed objects of a validated configuration (:func:`jointid.config.load_config`)."""
        return cls(model=ModelSpec.from_config(cfg), test_setup=TestSetup.from_config(cfg))

