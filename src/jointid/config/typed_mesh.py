"""The user's own structure read from a mesh file (``model: {kind: mesh}``) as typed, frozen objects.

:class:`MeshFileModel` holds the ``model`` section: the file, its bodies and their materials, the
joint layers (:class:`JointLayer`), the supports (:class:`Support`) and the added masses
(:class:`AddedMass`).  :func:`jointid.fe.meshmodel.build_mesh_model` assembles it.  It is part of
:class:`jointid.config.typed.ModelSpec`.
"""

from __future__ import annotations

import copyreg
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

__all__ = ["AddedMass", "JointLayer", "MeshFileModel", "Support", "read_only"]


def read_only(value: Any) -> Any:
    """``value`` with every mapping made a read-only copy and every list a tuple (recursively)."""
    if isinstance(value, Mapping):
        return MappingProxyType({k: read_only(v) for k, v in value.items()})
    if isinstance(value, (list, tuple)):
        return tuple(read_only(v) for v in value)
    return value


def _read_only_mapping(items: dict) -> MappingProxyType:
    return MappingProxyType(items)


def _reduce_read_only(proxy: MappingProxyType):
    return _read_only_mapping, (dict(proxy),)


# the typed objects go to a child process whole (jointid.diagnosis.refined): a read-only mapping pickles as
# a read-only mapping of the same items
copyreg.pickle(MappingProxyType, _reduce_read_only)


@dataclass(frozen=True)
class JointLayer:
    """A zero-thickness spring layer between two named surfaces (``model.joints[i]``).

    ``law``: component -> a joint parameter name or a stiffness per area in N/m^3; ``feed_axis``: the
    feed direction ``[x, y, z]`` (dimensionless; None when not given).
    """

    name: str
    surfaces: tuple[str, ...]
    law: Mapping[str, str | float]
    feed_axis: tuple[float, float, float] | None = None

    @property
    def identified(self) -> bool:
        """Whether a component of the layer is a joint parameter (not a fixed stiffness)."""
        return any(isinstance(v, str) for v in self.law.values())


@dataclass(frozen=True)
class Support:
    """A boundary condition on a named surface (``model.supports[i]``): clamped, or a foundation of
    ``k_N_per_m3`` per area (None when not given)."""

    surface: str
    kind: str
    k_N_per_m3: float | None = None


@dataclass(frozen=True)
class AddedMass:
    """A mass spread uniformly over a named surface (``model.masses[i]``), kg."""

    name: str
    surface: str
    mass_kg: float


@dataclass(frozen=True)
class MeshFileModel:
    """The ``model`` section of kind mesh: the mesh file and what its named groups are.

    ``bodies``: solid group -> material name; ``points``: the measuring-point file; ``point_tolerance_m``
    and ``max_gap_m``: the largest distance of a point from the surface and across a joint, m.
    """

    path: str
    bodies: Mapping[str, str]
    joints: tuple[JointLayer, ...] = ()
    supports: tuple[Support, ...] = ()
    masses: tuple[AddedMass, ...] = ()
    points: str = ""
    allow_linear: bool = False
    point_tolerance_m: float = 0.002
    max_gap_m: float = 0.001

    @classmethod
    def from_section(cls, section: Mapping) -> MeshFileModel:
        """The mesh-file model of a validated ``model`` section (kind mesh)."""
        joints = tuple(JointLayer(j["name"], tuple(j["surfaces"]), read_only(j["law"]),
                                  None if j.get("feed_axis") is None else tuple(j["feed_axis"]))
                       for j in section.get("joints", []))
        supports = tuple(Support(s["surface"], s["kind"], s.get("k_N_per_m3")) for s in section.get("supports", []))
        masses = tuple(AddedMass(m["name"], m["surface"], m["mass_kg"]) for m in section.get("masses", []))
        return cls(section.get("path", ""), read_only(section.get("bodies", {})), joints, supports, masses,
                   section.get("points", ""), section.get("allow_linear", False),
                   section.get("point_tolerance_m", 0.002), section.get("max_gap_m", 0.001))
