"""The affine FE model of a user's own structure, from a mesh file with named groups
(``model: {kind: mesh}``).

Terms (the same affine form as the rig's, :mod:`jointid.fe.model`):

=====================  ========================================================================
``K0``, ``M0``         the bodies (elasticity, consistent mass; materials from ``model.bodies``)
``K_<joint>_<comp>``   unit spring layer of a joint in one component (:mod:`jointid.fe.layer`)
``K_foundation``       unit springs per area to the ground on the clamped surfaces (coefficient 0:
                       the clamp holds; the diagnosis' ``base_support`` effect softens it)
``K_support<i>``       unit springs per area to the ground on the i-th support of kind foundation
``M_<mass>``           1 kg spread over the surface of an added mass
=====================  ========================================================================

Clamped supports fix the DOFs of their surface.  ``meta`` holds, besides the rig's keys, the joint
layers (``joints``: name, components, centre of the first surface) and the mass the joints carry
(``carried_mass_kg``: the bodies of the first, moving side of the identified joints that touch no
support, plus their added masses).  The measuring points of ``model.points`` are
projected onto the nearest surface of the mesh and interpolated there.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.sparse as sp

from jointid.config.typed import Material
from jointid.config.typed_mesh import MeshFileModel
from jointid.errors import ModelError
from jointid.fe import fem
from jointid.fe.layer import spring_layer_terms, surface_interpolation
from jointid.geometry.meshfile import MeshFile, read_mesh


def mesh_joint_terms(mesh_file: MeshFileModel) -> dict[str, list[str]]:
    """Joint parameter name -> the layer terms it multiplies (``K_<joint>_<component>``)."""
    out: dict[str, list[str]] = {}
    for joint in mesh_file.joints:
        for comp, value in joint.law.items():
            if isinstance(value, str):
                out.setdefault(value, []).append(f"K_{joint.name}_{comp}")
    return out


def mesh_constant_coefficients(mesh_file: MeshFileModel) -> tuple[dict[str, float], dict[str, float]]:
    """Coefficients that are not identified: joint components given in N/m^3, the foundation and
    the added masses.  Returns ``(k_coeffs, m_coeffs)``."""
    kc: dict[str, float] = {}
    for joint in mesh_file.joints:
        for comp, value in joint.law.items():
            if not isinstance(value, str):
                kc[f"K_{joint.name}_{comp}"] = float(value)
    for i, s in enumerate(mesh_file.supports):
        if s.kind == "foundation":
            kc[f"K_support{i}"] = float(s.k_N_per_m3)
    mc = {f"M_{m.name}": float(m.mass_kg) for m in mesh_file.masses}
    return kc, mc


def _problems(mfm: MeshFileModel, materials: Mapping[str, Material], mf: MeshFile) -> list[str]:
    """Every mismatch between ``model`` and the groups of the mesh file, one line each."""
    where = mf.path
    out = []
    known_s = set(mf.surfaces)
    for name, material in mfm.bodies.items():
        if name not in mf.cell_groups:
            out.append(f"{where}: model.bodies.{name}: no solid group {name!r} in the mesh — it has "
                       f"{mf.group_names()}; name a solid group")
        if material not in materials:
            out.append(f"model.bodies.{name}: unknown material {material!r} — use one of {sorted(materials)}")
    for i, joint in enumerate(mfm.joints):
        for s in joint.surfaces:
            if s not in known_s:
                out.append(f"{where}: model.joints[{i}] ({joint.name}): no surface group {s!r} in the mesh — "
                           f"it has {mf.group_names()}")
        if {"feed", "lateral"} & set(joint.law) and joint.feed_axis is None:
            out.append(f"model.joints[{i}] ({joint.name}): components feed/lateral need feed_axis "
                       "(the feed direction, e.g. [0, 0, 1])")
    for key in ("supports", "masses"):
        for i, item in enumerate(getattr(mfm, key)):
            if item.surface not in known_s:
                out.append(f"{where}: model.{key}[{i}]: no surface group {item.surface!r} in the mesh — "
                           f"it has {mf.group_names()}")
    for i, s in enumerate(mfm.supports):
        if s.kind == "foundation" and s.k_N_per_m3 is None:
            out.append(f"model.supports[{i}]: a foundation needs k_N_per_m3 (stiffness per area, N/m^3)")
    return out


def _cell_materials(mfm: MeshFileModel, materials: Mapping[str, Material], mf: MeshFile):
    """Per-cell Lamé constants and density, and the body index of each cell."""
    n = mf.mesh.t.shape[1]
    body = -np.ones(n, np.int64)
    names = list(mfm.bodies)
    for k, name in enumerate(names):
        cells = mf.cell_groups[name]
        twice = cells[body[cells] >= 0]
        if len(twice):
            other = names[body[twice[0]]]
            raise ModelError(f"{mf.path}: {len(twice)} cells are in both bodies {other!r} and {name!r} — a cell "
                             "belongs to one body; fix the groups or list only one of them in model.bodies")
        body[cells] = k
    if (body < 0).any():
        raise ModelError(f"{mf.path}: {int((body < 0).sum())} of {n} solid cells are in no group of model.bodies "
                         f"(listed: {names}; the mesh has {mf.group_names()}) — add their group to model.bodies")
    lam, mu, rho = (np.empty(n) for _ in range(3))
    for k, name in enumerate(names):
        m = materials[mfm.bodies[name]]
        sel = body == k
        lam[sel], mu[sel] = fem.lame(m.youngs_modulus_Pa, m.poisson_ratio)
        rho[sel] = m.density_kg_per_m3
    return lam, mu, rho, body


def read_points(path: str) -> pd.DataFrame:
    """Measuring points: a CSV with ``point, x_m, y_m, z_m`` (``part`` optional), or the node
    geometry (dataset 15 or 2411) of a Universal File (``.unv``/``.uff``; points named by node number)."""
    from jointid.errors import ConfigError

    if not path:
        raise ConfigError("model.points: no measuring-point file — give a CSV with columns point, x_m, y_m, z_m")
    if Path(path).suffix.lower() in (".unv", ".uff"):
        from jointid.data.uff import uff_points

        pts = uff_points(path)
        pts["part"] = ""
        return pts[["point", "part", "x_m", "y_m", "z_m"]]
    try:
        pts = pd.read_csv(path)
    except FileNotFoundError:
        raise ConfigError(f"model.points: {path}: no such file — give a CSV with columns point, x_m, y_m, z_m") from None
    missing = [c for c in ("point", "x_m", "y_m", "z_m") if c not in pts.columns]
    if missing:
        raise ConfigError(f"{path}: no column {', '.join(missing)} — the measuring points need point, x_m, y_m, z_m")
    if pts["point"].duplicated().any():
        raise ConfigError(f"{path}: point {pts['point'][pts['point'].duplicated()].iloc[0]!r} appears twice — "
                          "name every measuring point once")
    if "part" not in pts.columns:
        pts["part"] = ""
    return pts[["point", "part", "x_m", "y_m", "z_m"]].astype({"point": str, "part": str})


def build_mesh_model(mfm: MeshFileModel, materials: Mapping[str, Material], progress=None) -> fem.Model:
    """Assemble the model of a mesh file.

    Parameters
    ----------
    mfm : MeshFileModel
        The ``model`` section of kind mesh (:class:`jointid.config.typed_mesh.MeshFileModel`).
    materials : mapping of str to Material
        The materials by name (``materials``), for the bodies.
    progress : callable, optional
        Called with one line of text per step.
    """
    say = progress or (lambda msg: None)
    mf = read_mesh(mfm.path, allow_linear=mfm.allow_linear)
    problems = _problems(mfm, materials, mf)
    if problems:
        raise ModelError(problems)
    from skfem import Basis

    elem_cls, intorder = fem.ELEMENTS[mf.element]
    basis = Basis(mf.mesh, elem_cls(), intorder=intorder)
    lam, mu, rho, body = _cell_materials(mfm, materials, mf)
    K0, M0 = fem.assemble_elasticity(basis, lam, mu, rho)
    say(f"mesh: {mf.mesh.t.shape[1]} {mf.element} cells from {mf.path}, {3 * basis.N} DOFs")
    stiffness, areas = {"K0": K0}, {}
    for joint in mfm.joints:
        a, b = (mf.surfaces[s] for s in joint.surfaces)
        try:
            terms, info = spring_layer_terms(basis, a, b, list(joint.law), intorder=intorder,
                                             feed_axis=joint.feed_axis, max_gap_m=mfm.max_gap_m)
        except ValueError as exc:
            raise ModelError(f"{mf.path}: joint {joint.name} ({' - '.join(joint.surfaces)}): {exc} — check "
                             "the surface groups, or raise model.max_gap_m") from None
        for comp, K in terms.items():
            stiffness[f"K_{joint.name}_{comp}"] = K
        areas[joint.name] = info["area_m2"]
        say(f"joint {joint.name}: {info['area_m2']:.4g} m^2, largest gap {info['max_gap_m']:.2g} m")
    fixed = [np.array([], np.int64)]
    clamped = None
    for i, s in enumerate(mfm.supports):
        facets = mf.surfaces[s.surface]
        G = fem.ground_springs(fem.facet_mass(mf.mesh, basis.elem, facets, intorder))
        if s.kind == "clamped":
            sdofs = basis.get_dofs(facets=facets).all()
            fixed.append(np.concatenate([3 * sdofs + c for c in range(3)]))
            clamped = G if clamped is None else clamped + G
        else:
            stiffness[f"K_support{i}"] = G
    if clamped is not None:
        stiffness["K_foundation"] = clamped.tocsr()
    mass = {"M0": M0}
    for m in mfm.masses:
        mass[f"M_{m.name}"] = fem.surface_mass(fem.facet_mass(mf.mesh, basis.elem, mf.surfaces[m.surface], intorder))
    pts, probe = _probe(basis, mfm)
    dof_part = -np.ones(basis.N, dtype=int)
    for k in range(len(mfm.bodies)):
        dof_part[np.unique(basis.element_dofs[:, body == k])] = k
    meta = {"kind": "mesh", "n_elements": int(mf.mesh.t.shape[1]), "n_dofs": int(3 * basis.N),
            "element": mf.element, "bodies": list(mfm.bodies),
            "support": ",".join(sorted({s.kind for s in mfm.supports})) or "free",
            "contact_area_m2": areas, "points": pts.to_dict(orient="list"), "source": mf.path,
            "joints": _joint_meta(mf, mfm), "carried_mass_kg": _carried_mass(mf, mfm, basis, M0),
            "carriage_centres_m": _carriage_centres(mf, mfm)}
    model = fem.Model(stiffness=stiffness, mass=mass, fixed=np.unique(np.concatenate(fixed)), probe=probe,
                      doflocs=basis.doflocs, dof_part=dof_part, meta=meta)
    model.meta["mesh"] = {"p": mf.mesh.p, "t": mf.mesh.t, "part": body}
    return model


def _joint_meta(mf: MeshFile, mfm: MeshFileModel) -> list[dict]:
    """Name, components and centre (m, of the first surface's face centres) of each joint layer."""
    out = []
    for joint in mfm.joints:
        facets = mf.surfaces[joint.surfaces[0]]
        centre = mf.mesh.p[:, mf.mesh.facets[:, facets]].mean(axis=(1, 2))
        out.append({"name": joint.name, "components": list(joint.law), "centre_m": centre.tolist(),
                    "moving": joint.identified})
    return out


def _moving_facets(mf: MeshFile, mfm: MeshFileModel) -> np.ndarray:
    """Facets of the first (moving) surface of every joint with an identified component."""
    moving = [mf.surfaces[j.surfaces[0]] for j in mfm.joints if j.identified]
    return np.unique(np.concatenate(moving)) if moving else np.array([], np.int64)


def _carriage_centres(mf: MeshFile, mfm: MeshFileModel) -> list[list[float]]:
    """Centre (m) of each carriage: each connected patch (faces sharing a node) of the moving sides
    of the identified joints, e.g. a block's top and flank contacts together."""
    from scipy.sparse.csgraph import connected_components

    facets = _moving_facets(mf, mfm)
    if not len(facets):
        return []
    nodes = mf.mesh.facets[:, facets]
    inc = sp.csr_matrix((np.ones(nodes.size), (np.repeat(np.arange(len(facets)), nodes.shape[0]), nodes.T.ravel())),
                        shape=(len(facets), mf.mesh.p.shape[1]))
    n, label = connected_components(inc @ inc.T, directed=False)
    mid = mf.mesh.p[:, nodes].mean(axis=1)  # (3, n_facets)
    centres = [mid[:, label == k].mean(axis=1) for k in range(n)]
    order = np.lexsort(np.array(centres).T[[0, 2]])  # by Z, then X: a fixed numbering
    return [centres[k].tolist() for k in order]


def _carried_mass(mf: MeshFile, mfm: MeshFileModel, basis, M0) -> float:
    """Mass resting on the joints (kg): the bodies (connected by shared nodes) of the first surface of
    every joint with an identified component — the carried, moving side — that touch no support,
    plus the added masses on them."""
    from scipy.sparse.csgraph import connected_components

    t = mf.mesh.t
    n_cells, n_nodes = t.shape[1], mf.mesh.p.shape[1]
    incidence = sp.csr_matrix((np.ones(t.size), (np.repeat(np.arange(n_cells), t.shape[0]), t.T.ravel())),
                              shape=(n_cells, n_nodes))
    _, comp = connected_components(incidence @ incidence.T, directed=False)

    def comps(surface):
        return set(comp[mf.mesh.f2t[0, mf.surfaces[surface]]].tolist())

    moving = [j.surfaces[0] for j in mfm.joints if j.identified]
    joined = set().union(*[comps(s) for s in moving]) if moving else set()
    supported = set().union(*[comps(s.surface) for s in mfm.supports]) if mfm.supports else set()
    carried = joined - supported
    cells = np.flatnonzero(np.isin(comp, list(carried)))
    dofs = np.unique(basis.element_dofs[:, cells])
    ey = np.zeros(M0.shape[0])
    ey[1::3] = 1.0
    mass = float((M0 @ ey)[3 * dofs + 1].sum())
    return mass + sum(float(m.mass_kg) for m in mfm.masses if comps(m.surface) <= carried)


def _probe(basis, mfm: MeshFileModel):
    """Measuring points projected onto the nearest boundary face: the point table and the vector
    probe ``(3 n_points, 3 N)``."""
    pts = read_points(mfm.points)
    x = pts[["x_m", "y_m", "z_m"]].to_numpy(float).T
    P, dist, _ = surface_interpolation(basis, basis.mesh.boundary_facets(), x)
    far = np.flatnonzero(dist > mfm.point_tolerance_m)
    if len(far):
        raise ModelError([f"{mfm.points}: point {pts['point'].iloc[i]} is {dist[i]:.4g} m from the nearest surface "
                          f"of the mesh (tolerance model.point_tolerance_m = {mfm.point_tolerance_m} m) — "
                          "correct its coordinates (m, in the mesh's axes)" for i in far])
    return pts, fem.vector_rows(P)


def resolve(path: str, base: str | Path | None = None) -> str:
    """``path`` as given, or relative to ``base`` when it does not exist as given."""
    if base is None or Path(path).is_absolute() or Path(path).exists():
        return path
    return str(Path(base) / path)
