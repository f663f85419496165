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
        ``bottom`` the whole base bottom.
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


def build_mesh(rig: Rig, max_cell_m: float, refine: int = 1) -> RigMesh:
    """Mesh the rig with hexahedra whose grid lines pass through every part boundary."""
    x, y, z = (grid_lines(bp, max_cell_m, refine) for bp in rig.breakpoints)
    full = MeshHex.init_tensor(x, y, z)
    centroids = full.p[:, full.t].mean(axis=1).T
    part = rig.part_at(centroids)
    keep = part >= 0
    t = full.t[:, keep]
    part = part[keep]
    body = np.vectorize(BODY_OF_PART.get)(part)
    # duplicate the nodes used by both bodies; body 1 gets the copies
    used0 = np.zeros(full.p.shape[1], bool)
    used1 = np.zeros(full.p.shape[1], bool)
    used0[np.unique(t[:, body == 0])] = True
    used1[np.unique(t[:, body == 1])] = True
    shared = np.flatnonzero(used0 & used1)
    p = full.p
    new_index = np.arange(p.shape[1])
    new_index[shared] = p.shape[1] + np.arange(len(shared))
    p = np.hstack([p, p[:, shared]])
    t = t.copy()
    t[:, body == 1] = new_index[t[:, body == 1]]
    # drop unused nodes, renumber
    used = np.unique(t)
    remap = -np.ones(p.shape[1], int)
    remap[used] = np.arange(len(used))
    mesh = MeshHex(p[:, used], remap[t])
    return RigMesh(mesh=mesh, part=part, facets=_tag_facets(mesh, part, rig))


def _tag_facets(mesh: MeshHex, part: np.ndarray, rig: Rig) -> dict[str, np.ndarray]:
    bnd = mesh.boundary_facets()
    mid = mesh.p[:, mesh.facets[:, bnd]].mean(axis=1).T
    owner = mesh.f2t[0, bnd]
    body1 = np.isin(part[owner], [2, 3])
    out = {}
    for name in ("top", "flank"):
        out[name] = bnd[body1 & _in_patch(mid, rig.contact[name])]
    out["motor"] = bnd[body1 & _in_patch(mid, rig.patches["motor"])]
    body0 = ~body1
    out["mount"] = bnd[body0 & _in_patch(mid, rig.patches["mount"])] if rig.patches["mount"] else bnd[:0]
    out["bottom"] = bnd[body0 & (np.abs(mid[:, 1]) < _TOL)]
    return out
