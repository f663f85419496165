"""scikit-fem mesh of the rig: tensor-grid hexahedra, split into two bodies at the joint faces.

Nodes on the interface between body 0 (base + rails) and body 1 (carriages + table) are duplicated, so
the bodies share no degree of freedom; the joint springs (``jointid.fem``) are the only connection.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skfem import MeshHex

from .rig import BODY_OF_PART, Box, Rig, grid_lines

_TOL = 1e-9


@dataclass(frozen=True)
class RigMesh:
    """Mesh with tags.

    Attributes
    ----------
    mesh : skfem.MeshHex
    part : (n_elements,) int, part id of each element (``jointid.rig.PART_IDS``)
    facets : dict name -> (n,) facet indices; ``top`` / ``flank`` are the body-1 side of the joint
        faces, ``motor`` the table-underside patch, ``mount`` the base-bottom mount pads,
        ``bottom`` the whole base bottom, ``railfix`` the rail bottoms (rail side), ``table_edge``
        the table's +X side face, ``table_top`` the table's top face.
    """

    mesh: MeshHex
    part: np.ndarray
    facets: dict[str, np.ndarray]


def _in_patch(mid: np.ndarray, boxes: list[Box]) -> np.ndarray:
    mask = np.zeros(len(mid), bool)
    for box in boxes:
        lo, hi = np.asarray(box.lo), np.asarray(box.hi)
        mask |= np.all((mid >= lo - _TOL) & (mid <= hi + _TOL), axis=1)
    return mask


HALVE_CLASSES = ("plan", "thickness", "joint_zone")


def build_mesh(rig: Rig, max_cell_m: float, refine: int = 1, joint_cell_m: float | None = None,
               max_height_m: float | None = None, halve: tuple[str, ...] = ()) -> RigMesh:
    """Mesh the rig with hexahedra whose grid lines pass through every part boundary.

    ``max_height_m`` (m) caps the cell edge along Y, through the thickness of the plates, where the
    bending of base and table converges slowest; ``joint_cell_m`` (m) caps the cell size inside the
    joint zone (carriage footprints between the base top and the carriage top), where the contact
    strips load rail and carriage locally.  ``halve`` names classes of cells split in two, on top of
    ``refine``: ``plan`` (along X and Z), ``thickness`` (along Y), ``joint_zone`` (every axis, inside
    the joint zone); the result is the same mesh with those cells bisected (nested), so a solve on it
    is a one-step refinement study of the mesh without them.
    """
    unknown = set(halve) - set(HALVE_CLASSES)
    if unknown:
        raise ValueError(f"unknown cell classes to halve: {sorted(unknown)} (choose from {HALVE_CLASSES})")
    h_axes = (max_cell_m, min(max_cell_m, max_height_m or max_cell_m), max_cell_m)
    axis_halved = ("plan" in halve, "thickness" in halve, "plan" in halve)
    zone_refine = 2 * refine if "joint_zone" in halve else refine
    x, y, z = (grid_lines(bp, h, refine * (2 if halved else 1), zones, joint_cell_m, zone_refine)
               for bp, h, zones, halved in zip(rig.breakpoints, h_axes, rig.joint_zone, axis_halved))
    full = MeshHex.init_tensor(x, y, z)
    centroids = full.p[:, full.t].mean(axis=1).T
    part = rig.part_at(centroids)
    keep = part >= 0
    t = full.t[:, keep]
    part = part[keep]
    body = np.vectorize(BODY_OF_PART.get)(part)
    # every body after the first gets its own copies of the nodes it shares with earlier bodies
    p = full.p
    t = t.copy()
    taken = np.zeros(p.shape[1], bool)
    for b in np.unique(body):
        nodes = np.unique(t[:, body == b])
        shared = nodes[taken[nodes]]
        if len(shared):
            new_index = np.arange(p.shape[1])
            new_index[shared] = p.shape[1] + np.arange(len(shared))
            p = np.hstack([p, p[:, shared]])
            taken = np.concatenate([taken, np.zeros(len(shared), bool)])
            t[:, body == b] = new_index[t[:, body == b]]
            nodes = np.unique(t[:, body == b])
        taken[nodes] = True
    # drop unused nodes, renumber
    used = np.unique(t)
    remap = -np.ones(p.shape[1], int)
    remap[used] = np.arange(len(used))
    mesh = MeshHex(p[:, used], remap[t])
    return RigMesh(mesh=mesh, part=part, facets=_tag_facets(mesh, part, rig))


def mesh_from_config(rig: Rig, mesh_cfg: dict, refine: int | None = None, halve: tuple[str, ...] = ()) -> RigMesh:
    """Mesh the rig as the ``mesh`` section of the configuration asks (``refine`` overrides it;
    ``halve``: cell classes bisected on top, see :func:`build_mesh`)."""
    h = mesh_cfg["max_cell_size_m"]
    return build_mesh(rig, h, refine or mesh_cfg.get("refine", 1),
                      joint_cell_m=h * mesh_cfg.get("joint_cell_fraction", 1.0),
                      max_height_m=h * mesh_cfg.get("height_cell_fraction", 1.0), halve=tuple(halve))


def _tag_facets(mesh: MeshHex, part: np.ndarray, rig: Rig) -> dict[str, np.ndarray]:
    bnd = mesh.boundary_facets()
    mid = mesh.p[:, mesh.facets[:, bnd]].mean(axis=1).T
    owner = mesh.f2t[0, bnd]
    body1 = np.isin(part[owner], [2, 3])
    out = {}
    for name in ("top", "flank"):
        out[name] = bnd[body1 & _in_patch(mid, rig.contact[name])]
    out["motor"] = bnd[body1 & _in_patch(mid, rig.patches.get("motor", []))]
    base = part[owner] == 0
    rail = part[owner] == 1
    out["mount"] = bnd[base & _in_patch(mid, rig.patches.get("mount", []))]
    out["bottom"] = bnd[base & (np.abs(mid[:, 1]) < _TOL)]
    out["railfix"] = bnd[rail & _in_patch(mid, rig.patches.get("railfix", []))]
    out["table_edge"] = bnd[body1 & _in_patch(mid, rig.patches.get("table_edge", []))]
    out["table_top"] = bnd[body1 & _in_patch(mid, rig.patches.get("table_top", []))]
    return out
