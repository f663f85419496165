"""scikit-fem mesh of the rig: tensor-grid hexahedra, split into two bodies at the joint faces.

Nodes on the interface between body 0 (base + rails) and body 1 (carriages + table) are duplicated, so
the bodies share no degree of freedom; the joint springs (``jointid.fe.fem``) are the only connection.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skfem import MeshHex

from jointid.config.typed import MeshOptions
from jointid.geometry import localrefine
from jointid.geometry.rig import BONDED_GROUP_OF_PART, Box, Rig, body_of, grid_lines

_TOL = 1e-9


@dataclass(frozen=True)
class RigMesh:
    """Mesh with tags.

    Attributes
    ----------
    mesh : skfem.MeshHex
    part : (n_elements,) int, part id of each element (``jointid.geometry.rig.PART_IDS``)
    facets : dict name -> (n,) facet indices; ``top`` / ``flank`` are the body-1 side of the joint
        faces, ``motor`` the table-underside patch, ``mount`` the base-bottom mount pads,
        ``bottom`` the whole base bottom, ``railfix`` the rail bottoms (rail side), ``table_edge``
        the table's +X side face, ``table_top`` the table's top face.
    """

    mesh: MeshHex
    part: np.ndarray
    facets: dict[str, np.ndarray]
    boxes: tuple[np.ndarray, np.ndarray] | None = None  # (lo, hi) of every cell when nodes hang

    @property
    def body(self) -> np.ndarray:
        """Body of each element (``jointid.geometry.rig.BODY_OF_PART``)."""
        return body_of(self.part)


def _in_patch(mid: np.ndarray, boxes: list[Box]) -> np.ndarray:
    mask = np.zeros(len(mid), bool)
    for box in boxes:
        lo, hi = np.asarray(box.lo), np.asarray(box.hi)
        mask |= np.all((mid >= lo - _TOL) & (mid <= hi + _TOL), axis=1)
    return mask


HALVE_CLASSES = ("plan", "length", "thickness", "width", "joint_zone", "edges")


def axes_halved(halve: tuple[str, ...]) -> tuple[bool, bool, bool]:
    """Per axis (X, Y, Z), whether ``halve`` bisects every cell along it: ``length`` X, ``thickness`` Y,
    ``width`` Z, ``plan`` X and Z."""
    return ("plan" in halve or "length" in halve, "thickness" in halve, "plan" in halve or "width" in halve)


def build_mesh(rig: Rig, max_cell_m: float, refine: int = 1, joint_cell_m: float | None = None,
               max_height_m: float | None = None, halve: tuple[str, ...] = (), edge_levels: int = 0) -> RigMesh:
    """Mesh the rig with hexahedra whose grid lines pass through every part boundary.

    ``max_height_m`` (m) caps the cell edge along Y, through the thickness of the plates, where the
    bending of base and table converges slowest; ``joint_cell_m`` (m) caps the cell size inside the
    joint zone (carriage footprints between the base top and the carriage top), where the contact
    strips load rail and carriage locally.  ``halve`` names classes of cells split in two, on top of
    ``refine``: ``length`` (along X), ``thickness`` (along Y), ``width`` (along Z), ``plan`` (X and Z), ``joint_zone`` (every axis, inside
    the joint zone), ``edges`` (the cells at re-entrant edges, across the edge: one more
    ``edge_levels``); the result is the same mesh with those cells bisected (nested), so a solve on it
    is a one-step refinement study of the mesh without them.  ``edge_levels`` halves the cells that
    touch a re-entrant edge across it, that many times (``jointid.geometry.localrefine``; the mesh then has
    hanging nodes and ``boxes`` set); ``halve`` then bisects the cells of the locally refined mesh.
    """
    unknown = set(halve) - set(HALVE_CLASSES)
    if unknown:
        raise ValueError(f"unknown cell classes to halve: {sorted(unknown)} (choose from {HALVE_CLASSES})")
    h_axes = (max_cell_m, min(max_cell_m, max_height_m or max_cell_m), max_cell_m)
    axis_halved = axes_halved(halve)
    edge_levels = int(edge_levels) + ("edges" in halve)
    if edge_levels:
        lines = [grid_lines(bp, h, refine, zones, joint_cell_m)
                 for bp, h, zones in zip(rig.breakpoints, h_axes, rig.joint_zone)]
        return _edge_refined_mesh(rig, lines, edge_levels, halve, joint_cell_m or max_cell_m)
    zone_refine = 2 * refine if "joint_zone" in halve else refine
    x, y, z = (grid_lines(bp, h, refine * (2 if halved else 1), zones, joint_cell_m, zone_refine)
               for bp, h, zones, halved in zip(rig.breakpoints, h_axes, rig.joint_zone, axis_halved))
    full = MeshHex.init_tensor(x, y, z)
    centroids = full.p[:, full.t].mean(axis=1).T
    part = rig.part_at(centroids)
    keep = part >= 0
    t = full.t[:, keep]
    part = part[keep]
    body = body_of(part)
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


def mesh_from_config(rig: Rig, options: MeshOptions, refine: int | None = None, halve: tuple[str, ...] = ()) -> RigMesh:
    """Mesh the rig as the mesh options ask (:class:`jointid.config.typed.MeshOptions`, the ``mesh``
    section; ``refine`` overrides its own; ``halve``: cell classes bisected on top, see :func:`build_mesh`)."""
    h = options.max_cell_size_m
    return build_mesh(rig, h, refine or options.refine, joint_cell_m=h * options.joint_cell_fraction,
                      max_height_m=h * options.height_cell_fraction, halve=tuple(halve),
                      edge_levels=options.edge_refine_levels)


def _edge_refined_mesh(rig: Rig, lines: list[np.ndarray], levels: int, halve: tuple[str, ...],
                       margin_m: float) -> RigMesh:
    """Tensor grid on ``lines`` with the cells at re-entrant edges (within ``margin_m`` of the joint
    zone) refined ``levels`` times, then the ``halve`` classes bisected; after each step the cells
    on either side of every joint face are made to match (:func:`_match_joint_faces`)."""
    lo = np.stack(np.meshgrid(*[g[:-1] for g in lines], indexing="ij"), axis=-1).reshape(-1, 3)
    hi = np.stack(np.meshgrid(*[g[1:] for g in lines], indexing="ij"), axis=-1).reshape(-1, 3)
    part = rig.part_at(0.5 * (lo + hi))
    solid = part >= 0
    group = np.where(solid, np.vectorize(BONDED_GROUP_OF_PART.get)(np.maximum(part, 0)), -1)
    segments = localrefine.reentrant_segments(tuple(lines), group.reshape([len(g) - 1 for g in lines]))
    # only the edges in and around the joint zone (where the joints load the parts) are refined
    zone_lo = np.array([min(a for a, _ in z) for z in rig.joint_zone]) - margin_m
    zone_hi = np.array([max(b for _, b in z) for z in rig.joint_zone]) + margin_m
    segments = localrefine.clip_segments(segments, zone_lo, zone_hi)
    lo, hi, part = lo[solid], hi[solid], part[solid]
    level = np.zeros(len(lo), int)
    for _ in range(levels):  # each level made to match across the joint faces before the next
        lo, hi, level, part = localrefine.refine_at(lo, hi, segments, level, part)
        lo, hi, level, part = _match_joint_faces(rig, lo, hi, level, part)[:4]
    for axis, whole in enumerate(axes_halved(halve)):
        mask = np.full(len(lo), whole)
        if "joint_zone" in halve:
            mask |= np.array([any(a - 1e-9 <= l_ and h_ <= b + 1e-9 for a, b in rig.joint_zone[axis])
                              for l_, h_ in zip(lo[:, axis], hi[:, axis])], bool)
        lo, hi, level, part = localrefine.bisect(lo, hi, mask, axis, level, part)
    lo, hi, level, part, mesh, facets = _match_joint_faces(rig, lo, hi, level, part)
    return RigMesh(mesh=mesh, part=part, facets=facets, boxes=(lo, hi))


def _match_joint_faces(rig: Rig, lo, hi, level, part):
    """Split cells until the cells on either side of every joint face match (so that each node of a
    joint face has its partner on the other body).  Returns ``(lo, hi, level, part, mesh, facets)``."""
    for _ in range(64):
        body = body_of(part)
        mesh = localrefine.box_mesh(lo, hi, body)
        facets = _tag_facets(mesh, part, rig)
        mask = localrefine.unmatched_across(mesh, body, lo, hi,
                                            np.concatenate([facets[f] for f in ("top", "flank", "railfix")]))
        if not mask.any():
            return lo, hi, level, part, mesh, facets
        for axis in range(3):
            lo, hi, mask, level, part = localrefine.bisect(lo, hi, mask[:, axis], axis, mask, level, part)
    raise RuntimeError("joint faces of the locally refined mesh do not match after 64 passes")


def _tag_facets(mesh: MeshHex, part: np.ndarray, rig: Rig) -> dict[str, np.ndarray]:
    bnd = mesh.boundary_facets()
    mid = mesh.p[:, mesh.facets[:, bnd]].mean(axis=1).T
    owner = mesh.f2t[0, bnd]
    # a facet between cells of different size (hanging nodes) is unmatched but inside the body: drop it
    out_dir = mid - mesh.p[:, mesh.t[:, owner]].mean(axis=1).T
    axis = np.argmax(np.abs(out_dir), axis=1)
    beyond = mid.copy()
    beyond[np.arange(len(mid)), axis] += 1e-7 * np.sign(out_dir[np.arange(len(mid)), axis])
    outside = rig.part_at(beyond)
    inner = (outside >= 0) & (body_of(outside) == body_of(part[owner]))
    bnd, mid, owner = bnd[~inner], mid[~inner], owner[~inner]
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
