"""Build the affine FE model of the rig from the configuration, and cache it on disk.

``build_model(spec)`` runs rig geometry -> mesh -> assembly and returns a :class:`jointid.fe.fem.Model`
whose named terms are:

===============  ==============================================================================
``K0``           solids (elasticity)
``K_top_<d>``    unit spring layer on the rail-top contact faces, direction d in x, y, z
``K_flank_<d>``  unit spring layer on the rail-flank contact strips
``K_mount``      base mounts to ground, unit stiffness per area (all directions)
``K_railfix``    rail-bottom to base-top layer, unit stiffness per area (all directions)
``K_foundation`` base bottom to ground, unit stiffness per area (all directions)
``M0``           solids (consistent mass)
``M_motor``      1 kg spread over the table-underside motor patch
``M_table_top``  1 kg spread over the table top (e.g. a fixture or workpiece)
``M_table_edge`` 1 kg spread over the table's +X side face (e.g. cable chain, encoder head)
===============  ==============================================================================

and, apart from those (``Model.solids``, so that the solvers iterating over the affine terms do not
carry them), the solids per part of :data:`jointid.geometry.rig.PART_IDS`: ``K_solid_<part>``,
``M_solid_<part>``, the part's elasticity and mass at its reference material (``meta['solids']``).
``K0 = sum_b K_solid_b`` and ``M0 = sum_b M_solid_b``, so with coefficients
``c_b = E_b / E_b,ref - 1`` and ``m_b = rho_b / rho_b,ref - 1`` (0 at the reference)

    K = K0 + sum_b c_b K_solid_b + ...  = sum_b (E_b / E_b,ref) K_solid_b + sum_i theta_i K_i
    M = M0 + sum_b m_b M_solid_b + ...  = sum_b (rho_b / rho_b,ref) M_solid_b + sum_a m_a M_a

At each part's reference Poisson's ratio K_solid_b scales linearly with E_b; another Poisson's ratio
adds the part's volumetric term ``K_lambda_b`` (the Lamé split, :mod:`jointid.fe.lame`, assembled
when a configuration asks for it, not kept in the file).  The largest part (``meta['solids']['complement']``, the base)
is not stored: it is ``K0`` minus the other parts, formed when asked (:meth:`Model.solid_term`), so
the model file grows by the smaller parts only (about a quarter of ``K0`` and ``M0``), and ``K0`` and
``M0`` stay the mapped, shared arrays they were.  :func:`jointid.fe.solids.solid_coefficients` gives
``c_b`` and ``m_b`` of a configuration.

``joint_terms(joints)`` maps a joint parameter (``k_normal_N_per_m3`` ...) to the terms it multiplies.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from functools import partial
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from skfem import Basis

from jointid.config.typed import Joints, Material, ModelSpec, RigModel
from jointid.config.typed_mesh import MeshFileModel
from jointid.fe import fem
from jointid.fe.solids import (assemble_solid_parts, element_constants, motor_mass_kg,  # noqa: F401 (re-exported)
                               solid_coefficients)
from jointid.errors import ModelError
from jointid.geometry import localrefine
from jointid.io import map_npz, write_npz_mappable
from jointid.geometry.mesh import mesh_from_config
from jointid.geometry.points import measuring_points
from jointid.geometry.rig import PART_IDS, build_rig

RAIL_BONDED_N_PER_M3 = 1.0e15  # rail-to-base layer standing in for a bonded (consolidated) fixing


def joint_terms(joints: Joints, mesh_file: MeshFileModel | None = None) -> dict[str, list[str]]:
    """Stiffness terms multiplied by each joint parameter (identified and fixed ones).

    With ``mesh_file`` (a model read from a mesh file), its joint layers name the terms of each
    parameter (:func:`jointid.fe.meshmodel.mesh_joint_terms`).  On the rig, a parameter ``k_<kind>_N_per_m3`` with direction d acts on the face of its kind: ``normal`` on the
    rail top; ``lateral`` on the flanks (or the top for a flat joint); ``feed`` and any other kind on
    every contact face (top and flanks).
    """
    if mesh_file is not None:
        from jointid.fe.meshmodel import mesh_joint_terms

        return mesh_joint_terms(mesh_file)
    dirs = {p.name: p.direction for p in joints.parameters}
    for name in joints.fixed_N_per_m3:
        dirs.setdefault(name, {"normal": "y", "lateral": "x", "feed": "z"}.get(_kind(name), "z"))
    lateral_face = "flank" if joints.lateral_face == "flanks" else "top"
    out = {}
    for name, d in dirs.items():
        kind = _kind(name)
        if kind == "normal":
            faces = ["top"]
        elif kind == "lateral":
            faces = [lateral_face]
        else:
            faces = ["top", "flank"]
        out[name] = [f"K_{face}_{d}" for face in faces]
    return out


JOINT_FACES = ("top", "flank")
"""The rig's carriage-rail joint faces."""


def joint_layer_terms(model) -> frozenset:
    """The carriage-rail joint-layer terms of a model: on the rig ``K_<face>_<d>`` of the faces in
    :data:`JOINT_FACES`; on a mesh file every component of the joints with an identified component
    (not the fixed layers such as a bonded rail fixing)."""
    if model.meta.get("kind") == "mesh":
        return frozenset(f"K_{j['name']}_{c}" for j in model.meta["joints"] if j["moving"] for c in j["components"])
    return frozenset(n for n in model.stiffness
                     if n.startswith("K_") and n.count("_") == 2 and n.split("_")[1] in JOINT_FACES)


def _kind(name: str) -> str:
    return name.split("_")[1] if name.startswith("k_") else name


def edge_level_model(spec: ModelSpec, extra: int, progress=None, ordering: bool = True):
    """The model of ``spec`` with ``extra`` more edge-refinement levels; with ``ordering``, with its
    fill-reducing ordering (:func:`jointid.fe.modal.model_ordering`: the pattern, so its ordering, is the
    same at any shift), for a model factorised many times (the run's model, kept in its file)."""
    from jointid.fe.modal import model_ordering

    model = build_model(spec.with_edge_levels(extra), progress=progress)
    model.ordering = model_ordering(model) if ordering else None
    return model


def edge_level_builders(spec: ModelSpec, levels=None, progress=None) -> list:
    """Functions that each build the model with one of ``levels`` more edge levels
    (:func:`edge_level_model`; default: those the extrapolation solves,
    :attr:`jointid.config.typed.MeshOptions.edge_extra_levels`), called when its turn comes, so that
    only one is held at a time.  Each is solved once, so without a separate ordering step: its one
    factorisation finds the ordering itself (on the default mesh's +1 level, 85 170 DOFs, the separate
    step took 4.5 s and saved that factorisation 1 s)."""
    return [partial(edge_level_model, spec, k, progress, ordering=False)
            for k in (levels or spec.mesh.edge_extra_levels)]


def build_model(spec: ModelSpec, *, refine: int | None = None, halve: tuple[str, ...] = (), rig=None,
                progress=None) -> fem.Model:
    """Assemble the FE model described by ``spec``.

    Parameters
    ----------
    spec : ModelSpec
        The model (:meth:`jointid.config.typed.ModelSpec.from_config`).
    refine, halve
        Refinement of the rig's mesh (see :func:`jointid.geometry.mesh.build_mesh`).
    rig : jointid.geometry.rig.Rig, optional
        A geometry to use instead of the one built from ``spec.rig`` (e.g. with extra grid breakpoints).
    progress : callable, optional
        Called with one line of text per step.

    With a mesh file (``spec.mesh_file``) the model is read from it instead
    (:func:`jointid.fe.meshmodel.build_mesh_model`; no refinement).
    """
    if spec.is_mesh_file:
        if refine not in (None, 1) or halve:
            raise ModelError("model.kind: mesh: a mesh file is solved as it is — refinement (mesh.refine, "
                             "mesh_check, mesh.extrapolate_edges) works on the parametric rig only; "
                             "refine the mesh in the tool that made it")
        from jointid.fe.meshmodel import build_mesh_model

        return build_mesh_model(spec.mesh_file, spec.materials, progress)
    say = progress or (lambda msg: None)
    element = spec.mesh.element
    rig = rig or build_rig(spec.rig.geometry)
    rmesh = mesh_from_config(rig, spec.mesh, refine, halve)
    facet_masses: dict[str, sp.csr_matrix] = {}  # face -> its facet mass, assembled once per build
    basis, stiffness, M0, dof_body = assemble_solids_and_joints(spec.materials, rig, rmesh, element, facet_masses)
    solids, solids_meta = assemble_solid_parts(spec.materials, rig, rmesh, basis)
    elem, intorder = basis.elem, fem.ELEMENTS[element][1]
    doflocs = basis.doflocs
    say(f"mesh: {rmesh.mesh.t.shape[1]} {element} elements, {3 * basis.N} DOFs")

    def facet_mass(face: str) -> sp.csr_matrix:
        if face not in facet_masses:
            facet_masses[face] = fem.facet_mass(rmesh.mesh, elem, rmesh.facets[face], intorder)
        return facet_masses[face]

    S_fix = facet_mass("railfix")
    stiffness["K_railfix"] = sum(fem.spring_layer(S_fix, doflocs, i, dof_body) for i in range(3)).tocsr()
    stiffness["K_foundation"] = fem.ground_springs(facet_mass("bottom"))
    support = spec.rig.support_kind
    fixed = np.array([], dtype=np.int64)
    if support == "mounts":
        stiffness["K_mount"] = fem.ground_springs(facet_mass("mount"))
    elif support == "clamped":
        sdofs = basis.get_dofs(facets=rmesh.facets["bottom"]).all()
        fixed = np.sort(np.concatenate([3 * sdofs + c for c in range(3)]))
    mass = {"M0": M0}
    for name, facets in (("motor", "motor"), ("table_top", "table_top"), ("table_edge", "table_edge")):
        mass[f"M_{name}"] = fem.surface_mass(facet_mass(facets))
    pts = measuring_points(spec.rig.geometry, rig.dims)
    xyz = pts[["x_m", "y_m", "z_m"]].to_numpy().T.copy()
    xyz[1] -= 1e-7  # nudge onto the solid side of the top surfaces
    P = basis.probes(xyz)  # (n_pts, N) scalar
    probe = fem.vector_rows(P)
    dof_part = dof_parts(basis, rmesh)
    areas = {face: float(facet_mass(face).sum()) for face in ("top", "flank", "motor", "mount")}
    meta = {"n_elements": int(rmesh.mesh.t.shape[1]), "n_dofs": int(3 * basis.N),
            "element": element, "support": support,
            "contact_area_m2": {"top": areas["top"], "flank": areas["flank"]},
            "mount_area_m2": areas["mount"], "motor_patch_area_m2": areas["motor"],
            "motor_mass_kg": spec.rig.motor_mass_kg,
            "mount_area_each_m2": areas["mount"] / 4 if support == "mounts" else 0.0,
            "carriage_centres_m": rig.carriage_centres.tolist(), "dims_m": rig.dims,
            "points": pts.to_dict(orient="list"), "solids": solids_meta}
    model = fem.Model(stiffness=stiffness, mass=mass, fixed=fixed, probe=probe, doflocs=doflocs,
                      dof_part=dof_part, meta=meta, solids=solids)
    model.meta["mesh"] = {"p": rmesh.mesh.p, "t": rmesh.mesh.t, "part": rmesh.part}
    if rmesh.boxes is not None:
        lo, hi = rmesh.boxes
        T, free = localrefine.hanging_constraints(doflocs, basis.element_dofs, lo, hi, rmesh.body,
                                                  localrefine.ORDER[element])
        say(f"hanging nodes: {basis.N - len(free)} of {basis.N} nodes tied, {3 * len(free)} DOFs left")
        model = _constrained(model, T, free)
    return model


def assemble_solids_and_joints(materials: Mapping[str, Material], rig, rmesh, element: str,
                               facet_masses: dict | None = None):
    """Elasticity of the solids (``materials`` by name) on ``rmesh`` and the unit joint spring layers.

    Returns ``(basis, stiffness, M0, dof_body)``: ``stiffness`` holds ``K0`` and ``K_<face>_<d>`` for
    the faces ``top`` and ``flank`` (see the module docstring); ``dof_body`` is the body of each scalar
    DOF when the mesh has hanging nodes (else None).  ``facet_masses``: a dict that receives the two
    faces' facet masses (the caller's areas use them again).
    """
    elem_cls, intorder = fem.ELEMENTS[element]
    elem = elem_cls()
    basis = Basis(rmesh.mesh, elem, intorder=intorder)
    lam, mu, rho, _ = element_constants(materials, rig, rmesh)
    K0, M0 = fem.assemble_elasticity(basis, lam, mu, rho)
    stiffness = {"K0": K0}
    dof_body = None
    if rmesh.boxes is not None:
        dof_body = np.empty(basis.N, np.int64)
        dof_body[basis.element_dofs] = rmesh.body[None, :]
    for face in ("top", "flank"):
        S = fem.facet_mass(rmesh.mesh, elem, rmesh.facets[face], intorder)
        if facet_masses is not None:
            facet_masses[face] = S
        for d, i in fem.DIRS.items():
            stiffness[f"K_{face}_{d}"] = fem.spring_layer(S, basis.doflocs, i, dof_body)
    return basis, stiffness, M0, dof_body


def dof_parts(basis, rmesh) -> np.ndarray:
    """Part id of each scalar DOF (the last part in id order wins on shared nodes; -1: none)."""
    part = -np.ones(basis.N, dtype=int)
    for pid in np.unique(rmesh.part):
        part[np.unique(basis.element_dofs[:, rmesh.part == pid])] = pid
    return part


def _constrained(model: fem.Model, T: sp.csr_matrix, free: np.ndarray) -> fem.Model:
    """``model`` on the free nodes of a mesh with hanging nodes: every matrix projected with the
    scalar map ``T`` (all nodes from the free ones, ``jointid.geometry.localrefine.hanging_constraints``);
    ``free[j]`` is a node standing for free node j (its location and part)."""
    Tv = sp.kron(T, sp.eye(3), format="csr")
    Tt = Tv.T.tocsr()
    project = {g: {name: (Tt @ A @ Tv).tocsr() for name, A in getattr(model, g).items()}
               for g in ("stiffness", "mass", "solids")}
    # the free nodes a clamped node is made of: itself, or (hanging) the nodes of the clamped face
    # it hangs on, which are clamped too
    fixed_free = np.unique(T[np.unique(model.fixed // 3)].indices)
    fixed = np.sort(np.concatenate([3 * fixed_free + c for c in range(3)]))
    meta = dict(model.meta)
    meta["n_dofs"] = int(3 * len(free))
    vertex = T[: model.meta["mesh"]["p"].shape[1]].tocsr()  # vertex dofs come first
    meta["mesh"] = dict(model.meta["mesh"], vertex_data=vertex.data, vertex_indices=vertex.indices,
                        vertex_indptr=vertex.indptr)
    return fem.Model(stiffness=project["stiffness"], mass=project["mass"], fixed=fixed,
                     probe=(model.probe @ Tv).tocsr(), doflocs=model.doflocs[:, free],
                     dof_part=model.dof_part[free], meta=meta, solids=project["solids"])


def joint_coefficients(joints: Joints, theta: dict[str, float] | None = None,
                       mesh_file: MeshFileModel | None = None) -> dict[str, float]:
    """Coefficient of every joint spring term (``K_top_y`` ...) at joint parameters ``theta`` (N/m^3;
    defaults: :meth:`jointid.config.typed.Joints.defaults_N_per_m3`); ``mesh_file``: the model's mesh
    file, if any (its layers name the terms)."""
    values = joints.defaults_N_per_m3()
    if theta:
        values.update(theta)
    kc: dict[str, float] = {}
    for name, terms in joint_terms(joints, mesh_file).items():
        for term in terms:
            kc[term] = kc.get(term, 0.0) + values.get(name, 0.0)
    return kc


def base_coefficients(spec: ModelSpec, model: fem.Model, theta: dict[str, float] | None = None,
                      extra_k: dict[str, float] | None = None):
    """Stiffness and mass coefficients of the model at joint parameters ``theta``.

    Parameters
    ----------
    spec : ModelSpec
        The model's description (joints, rig or mesh file, materials).
    model : jointid.fe.fem.Model
        The assembled model (its mount area and reference materials).
    theta : dict, optional
        Joint parameter name -> stiffness per area, N/m^3 (defaults: the geometric mean of the bounds
        for identified parameters, the configured value for fixed ones).
    extra_k : dict, optional
        Stiffness coefficients added to those of the model (term name -> coefficient).

    Returns
    -------
    tuple of dict
        ``(k_coeffs, m_coeffs)`` for :meth:`Model.K` and :meth:`Model.M`: the joints, the rail fixing
        and mounts, the motor mass (``M_motor``, kg) and the solids' material ratios
        (:func:`solid_coefficients`, none when the materials are the model's own).
    """
    if spec.is_mesh_file:
        from jointid.fe.meshmodel import mesh_constant_coefficients

        kc, mc = mesh_constant_coefficients(spec.mesh_file)
        for name, v in joint_coefficients(spec.joints, theta, spec.mesh_file).items():
            kc[name] = kc.get(name, 0.0) + v
        for name, v in (extra_k or {}).items():
            kc[name] = kc.get(name, 0.0) + v
        return kc, mc
    kc = joint_coefficients(spec.joints, theta)
    kc["K_railfix"] = rail_fixing_N_per_m3(spec.rig)
    if "K_mount" in model.stiffness:
        kc["K_mount"] = spec.rig.k_mount_N_per_m / model.meta["mount_area_each_m2"]
    for name, v in (extra_k or {}).items():
        kc[name] = kc.get(name, 0.0) + v
    mc = {"M_motor": motor_mass_kg(spec.rig)}
    ks, ms = solid_coefficients(spec, model)
    kc.update(ks)
    mc.update(ms)
    return kc, mc


def rail_fixing_N_per_m3(rig: RigModel) -> float:
    """The rail-to-base layer's stiffness per area, N/m^3 (``RAIL_BONDED_N_PER_M3`` for a bonded fixing)."""
    return float(RAIL_BONDED_N_PER_M3 if rig.rail_fixing_N_per_m3 is None else rig.rail_fixing_N_per_m3)


# ---------------------------------------------------------------- cache
def save_model(model: fem.Model, path: str | Path) -> None:
    """Write the model to one ``.npz`` file atomically (temporary file + rename)."""
    write_npz_mappable(Path(path), _model_arrays(model))


def stored_model(model: fem.Model) -> fem.Model:
    """``model`` as :func:`load_model` reads back the file :func:`save_model` writes of it (CSR matrices, the
    terms in name order, the description through JSON), without the file: the same numbers in every solve."""
    return _model_of(_model_arrays(model))


def _model_arrays(model: fem.Model) -> dict[str, np.ndarray]:
    """The arrays of the model file (:func:`save_model`)."""
    arrays = {}
    for group in ("stiffness", "mass", "solids"):
        for name, A in getattr(model, group).items():
            A = A.tocsr()
            for part in ("data", "indices", "indptr"):
                arrays[f"{group}/{name}/{part}"] = getattr(A, part)
            arrays[f"{group}/{name}/shape"] = np.array(A.shape)
    P = model.probe.tocsr()
    for part in ("data", "indices", "indptr"):
        arrays[f"probe/{part}"] = getattr(P, part)
    arrays["probe/shape"] = np.array(P.shape)
    arrays["fixed"] = model.fixed
    arrays["doflocs"] = model.doflocs
    arrays["dof_part"] = model.dof_part
    if model.ordering is not None:
        arrays["ordering"] = model.ordering
    mesh = model.meta.get("mesh", {})
    for k, v in mesh.items():
        arrays[f"mesh/{k}"] = v
    meta = {k: v for k, v in model.meta.items() if k != "mesh"}
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    return arrays


def load_model(path: str | Path) -> fem.Model:
    """Read a model written by :func:`save_model`.

    The arrays are memory-mapped (:func:`jointid.io.map_npz`), not read: a job pages in only what it
    touches, and the jobs running at once on one machine share one copy of the model in the page
    cache.  They are read-only; every model operation makes new matrices.
    """
    import zipfile

    from jointid.errors import ModelError

    hint = "point to results/model/matrices.npz, written by the mesh rule"
    try:
        z = map_npz(path)
    except FileNotFoundError:
        raise ModelError(f"{path}: no such model file — {hint}") from None
    except (zipfile.BadZipFile, ValueError, OSError) as exc:
        raise ModelError(f"{path}: not a readable .npz file ({exc}) — {hint}") from None
    missing = [k for k in ("stiffness/K0/data", "mass/M0/data", "probe/data", "fixed", "doflocs", "meta")
               if k not in z]
    if missing:
        raise ModelError(f"{path}: not a jointid model file (no {', '.join(missing)}) — {hint}")
    return _model_of(z)


def _model_of(z) -> fem.Model:
    """The model of the arrays of a model file (:func:`_model_arrays`; a mapping of name -> array)."""
    groups: dict[str, dict[str, sp.csr_matrix]] = {"stiffness": {}, "mass": {}, "solids": {}}
    names = {(k.split("/")[0], k.split("/")[1]) for k in z if k.startswith(("stiffness/", "mass/", "solids/"))}
    for group, name in sorted(names):
        pre = f"{group}/{name}/"
        groups[group][name] = sp.csr_matrix((z[pre + "data"], z[pre + "indices"], z[pre + "indptr"]),
                                            shape=tuple(z[pre + "shape"]))
    probe = sp.csr_matrix((z["probe/data"], z["probe/indices"], z["probe/indptr"]), shape=tuple(z["probe/shape"]))
    meta = json.loads(bytes(z["meta"]).decode())
    meta["mesh"] = {k.split("/")[1]: z[k] for k in z if k.startswith("mesh/")}
    return fem.Model(stiffness=groups["stiffness"], mass=groups["mass"], fixed=z["fixed"], probe=probe,
                     doflocs=z["doflocs"], dof_part=z["dof_part"], meta=meta,
                     ordering=z["ordering"] if "ordering" in z else None, solids=groups["solids"])
