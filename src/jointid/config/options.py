"""Typed options of the workflow's stages: the config dict turned, once and at the edge, into what a stage reads.

A rule script (``workflow/scripts/*.py``), the Snakefile or the API builds a stage's options from the
configuration with ``<Options>.from_config(cfg)`` and passes them to the stage function of
:mod:`jointid.stages`; no function below ``config/`` takes the dict (``tools/layout.py`` checks it).
A rule gets only the config keys it hashes (``params: cfg=``, the ``CONFIG`` of its stage module), so
each ``from_config`` reads only those.  A key a section does not give takes the schema's default
(:func:`jointid.config.schema.given`): the defaults live in ``schema.yaml`` alone.

* :class:`DoeOptions` - rules ``doe`` and ``doe_zoom``;
* :class:`SurfaceOptions` - rules ``fit_surface`` and ``fit_zoom``;
* :class:`IdentifyOptions` - rules ``scout`` and ``identify``;
* :class:`CarriageOptions` - rule ``carriage_rigidity``;
* :class:`MeshCheckOptions` - rule ``mesh_check``;
* :class:`HarmonicOptions` - rule ``harmonic`` (and its FRF comparison);
* :class:`Table1Options` - rule ``table1``'s ranges;
* :class:`ReportOptions` - rule ``report``.

Rules ``mesh``, ``modal``, ``rom`` and ``verify`` read the model alone: they take a
:class:`jointid.config.typed.ModelSpec`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from jointid.config.datasets import dataset_folder
from jointid.config.hashing import ConfigStamp
from jointid.config.schema import default as schema_default
from jointid.config.schema import given
from jointid.config.typed import Damping, Joints, ModelSpec, TestSetup, read_only

__all__ = ["CarriageOptions", "DoeOptions", "HarmonicOptions", "IdentifyOptions", "MeshCheckOptions",
           "ReportOptions", "SurfaceOptions", "Table1Options", "given"]


def _weights(section: Mapping) -> tuple[float, ...] | None:
    """``identify.weights`` as given (None: not given or empty, every mode weighs one)."""
    w = section.get("weights")
    return tuple(w) if w else None


@dataclass(frozen=True)
class DoeOptions:
    """The DOE sample sheets (``doe``; ``joints`` for the box): the design, its seed and the zoom."""

    joints: Joints
    design: str
    n_center: int
    n_samples: int
    seed: int
    n_verification: int
    zoom_enabled: bool
    zoom_half_width_decades: float

    @classmethod
    def from_config(cls, cfg: Mapping) -> DoeOptions:
        """The DOE of a configuration (sections ``joints`` and ``doe``; without ``doe.zoom`` the schema's)."""
        d = cfg["doe"]
        zoom = d.get("zoom") or {}
        return cls(Joints.from_section(cfg["joints"]), d["design"], d["n_center"], given(d, "n_samples", "doe.n_samples"),
                   d["seed"], d["n_verification"], bool(given(zoom, "enabled", "doe.zoom.enabled")),
                   float(given(zoom, "half_width_decades", "doe.zoom.half_width_decades")))


@dataclass(frozen=True)
class SurfaceOptions:
    """The response surfaces (``surface``): their kind, the verification limit (%), the tracked band (Hz)."""

    joints: Joints
    kind: str
    max_verification_error_pct: float
    tracked_band_Hz: tuple[float, float]

    @classmethod
    def from_config(cls, cfg: Mapping) -> SurfaceOptions:
        """Sections ``joints``, ``surface``, keys ``solver.min_freq_Hz`` and ``harmonic.band_Hz``: the modes of the
        reference point from the lowest tracked frequency to 1.25 times the band's top are tracked and fitted."""
        s = cfg["surface"]
        band = (float(cfg["solver"]["min_freq_Hz"]), 1.25 * float(cfg["harmonic"]["band_Hz"][1]))
        return cls(Joints.from_section(cfg["joints"]), s["kind"], s["max_verification_error_pct"], band)


@dataclass(frozen=True)
class IdentifyOptions:
    """One state's identification (``identify``) and what it reads beside: the model (sections a rule
    ``scout`` lacks are None), the test setup, the configured damping (the tie rule) and the states'
    dataset folders (``datasets``: state -> folder)."""

    model: ModelSpec
    n_starts: int
    seed: int
    frequency_uncertainty_pct: float
    weights: tuple[float, ...] | None
    fe_polish: bool
    pairing: str
    min_freq_Hz: float
    test_setup: TestSetup
    damping: Damping
    datasets: Mapping[str, str]

    @classmethod
    def from_config(cls, cfg: Mapping, states: list[str]) -> IdentifyOptions:
        """The options of rule ``identify`` or ``scout`` (their config keys: :func:`jointid.config.rule_keys.identify`)
        for the states ``states`` (the state identified and those it is paired with)."""
        ic = cfg["identify"]
        return cls(ModelSpec.from_config(cfg), ic["n_starts"], ic["seed"], ic["frequency_uncertainty_pct"],
                   _weights(ic), bool(given(ic, "fe_polish", "identify.fe_polish")), ic["pairing"],
                   float(cfg["solver"]["min_freq_Hz"]), TestSetup.from_config(cfg),
                   Damping.from_section((cfg.get("harmonic") or {}).get("damping")),
                   read_only({s: dataset_folder(cfg, s) for s in states}))

    @property
    def extrapolate_edges(self) -> bool:
        """Whether the polish is repeated on mesh-extrapolated frequencies (``mesh.extrapolate_edges``; no mesh
        section, as in rule ``scout``: no)."""
        return bool(self.model.mesh is not None and self.model.mesh.extrapolate_edges)


@dataclass(frozen=True)
class CarriageOptions:
    """The catalogue-style test of one carriage (``carriage_rigidity``): the model, the test's cell size (m)
    and the ``catalogue`` section (None without one)."""

    model: ModelSpec
    cell_size_m: float
    catalogue: Mapping | None

    @classmethod
    def from_config(cls, cfg: Mapping) -> CarriageOptions:
        """Sections ``materials, rig, joints, carriage_rigidity, catalogue``, keys ``mesh.element``, ``solver.backend``."""
        return cls(ModelSpec.from_config(cfg), cfg["carriage_rigidity"]["cell_size_m"], cfg.get("catalogue"))


@dataclass(frozen=True)
class MeshCheckOptions:
    """The mesh check (``mesh_check``): the cells halved, whether both meshes are extrapolated over their edge
    levels, the limit on a parameter's change (%), the share of the model error the mesh may take, and the
    modes' weights (``identify.weights``; None: ones)."""

    model: ModelSpec
    halve: tuple[str, ...]
    edge_levels: bool
    max_parameter_change_pct: float
    budget_fraction: float
    weights: tuple[float, ...] | None

    @classmethod
    def from_config(cls, cfg: Mapping) -> MeshCheckOptions:
        """Sections ``materials, rig, model, mesh, mesh_check, joints``, ``identify.weights`` and the solve's keys."""
        mc = cfg["mesh_check"]
        return cls(ModelSpec.from_config(cfg), tuple(mc["halve"]), bool(given(mc, "edge_levels", "mesh_check.edge_levels")),
                   float(mc["max_parameter_change_pct"]), float(given(mc, "budget_fraction", "mesh_check.budget_fraction")),
                   _weights(cfg["identify"]))

    @property
    def extrapolate(self) -> bool:
        """Both meshes extrapolated over their edge levels: ``mesh_check.edge_levels`` and ``mesh.extrapolate_edges``."""
        return bool(self.edge_levels and self.model.mesh.extrapolate_edges)


@dataclass(frozen=True)
class HarmonicOptions:
    """One state's harmonic analysis (``harmonic``): the model, the band (Hz) and its number of frequencies,
    the drive point, direction and hammer-tip diameter (m), the damping model (``damping``: the section as
    given without its range, as ``dynamic_stiffness.json`` records it), Table 1's assumed range of damping
    ratios, and the state's dataset folder (measured damping ratios and FRFs)."""

    model: ModelSpec
    band_Hz: tuple[float, float]
    n_freq: int
    drive_point: str
    direction: str
    patch_diameter_m: float
    damping: Mapping
    damping_ratio_range: tuple[float, float]
    dataset: str

    @classmethod
    def from_config(cls, cfg: Mapping, state: str) -> HarmonicOptions:
        """The options of rule ``harmonic`` for ``state`` (its keys: :func:`jointid.config.rule_keys.harmonic`)."""
        h = cfg["harmonic"]
        section = h.get("damping") or {}
        damping = dict(section or {"model": schema_default("harmonic.damping.model"),
                                   "damping_ratio": schema_default("harmonic.damping.damping_ratio")})
        damping.pop("damping_ratio_range", None)  # the model's own fields; the range is Table 1's
        return cls(ModelSpec.from_config(cfg), tuple(float(b) for b in h["band_Hz"]), int(h["n_freq"]),
                   h["drive_point"], given(h, "direction", "harmonic.direction"),
                   float(given(h, "patch_diameter_m", "harmonic.patch_diameter_m")), read_only(damping),
                   tuple(given(section, "damping_ratio_range", "harmonic.damping.damping_ratio_range")),
                   dataset_folder(cfg, state))

    @property
    def damping_model(self) -> Damping:
        """The configured damping model (:class:`jointid.config.typed.Damping`)."""
        return Damping.from_section(self.damping)


@dataclass(frozen=True)
class Table1Options:
    """Table 1's ranges (rule ``table1``): the band (Hz; None: the harmonic stage's) and its number of frequencies."""

    band_Hz: tuple[float, float] | None
    n_freq: int

    @classmethod
    def from_config(cls, cfg: Mapping | None) -> Table1Options:
        """From the ``harmonic`` section's ``band_Hz`` and ``n_freq`` (no section: the schema's ``n_freq``)."""
        h = (cfg or {}).get("harmonic", {})
        band = h.get("band_Hz")
        return cls(None if band is None else tuple(band), int(given(h, "n_freq", "harmonic.n_freq")))


@dataclass(frozen=True)
class ReportOptions:
    """What the report page reads of the whole configuration: the identified parameters' bounds (N/m^3),
    the surfaces' verification limit (%; None without a ``surface`` section), the configuration as the page
    shows it (YAML text) and its :class:`~jointid.config.hashing.ConfigStamp`."""

    bounds_N_per_m3: Mapping[str, tuple[float, float]]
    max_verification_error_pct: float | None
    config_yaml: str
    stamp: ConfigStamp

    @classmethod
    def from_config(cls, cfg: Mapping) -> ReportOptions:
        """The report's options of the whole configuration."""
        import yaml

        bounds = {n: (s["lower"], s["upper"]) for n, s in cfg.get("joints", {}).get("parameters", {}).items()}
        return cls(read_only(bounds), cfg.get("surface", {}).get("max_verification_error_pct"),
                   yaml.safe_dump(cfg, sort_keys=False, default_flow_style=None, width=110), ConfigStamp.of(cfg))
