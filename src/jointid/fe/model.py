"""Build the affine FE model of the rig from the configuration, and cache it on disk.

``build_model(cfg)`` runs rig geometry -> mesh -> assembly and returns a :class:`jointid.fe.fem.Model`
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

Poisson's ratio of each part is fixed at its reference (then K_solid_b scales linearly with E_b); a
change of it needs a model of its own.  The largest part (``meta['solids']['complement']``, the base)
is not stored: it is ``K0`` minus the other parts, formed when asked (:meth:`Model.solid_term`), so
the model file grows by the smaller parts only (about a quarter of ``K0`` and ``M0``), and ``K0`` and
``M0`` stay the mapped, shared arrays they were.  :func:`jointid.fe.solids.solid_coefficients` gives
``c_b`` and ``m_b`` of a configuration.

``joint_terms(cfg)`` maps a joint parameter (``k_normal_N_per_m3`` ...) to the terms it multiplies.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from skfem import Basis

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


def joint_terms(joints_cfg: dict, model_cfg: dict | None = None) -> dict[str, list[str]]:
    """Stiffness terms multiplied by each joint parameter (identified and fixed ones).

    With ``model_cfg`` of kind mesh, the layers of ``model_cfg['joints']`` name the terms of each
    parameter (:func:`jointid.fe.meshmodel.mesh_joint_terms`).  On the rig, a parameter ``k_<kind>_N_per_m3`` with direction d acts on the face of its kind: ``normal`` on the
    rail top; ``lateral`` on the flanks (or the top for a flat joint); ``feed`` and any other kind on
    every contact face (top and flanks).
    """
    if (model_cfg or {}).get("kind", "rig") == "mesh":
        from jointid.fe.meshmodel import mesh_joint_terms

        return mesh_joint_terms(model_cfg)
    params = dict(joints_cfg.get("parameters", {}))
    dirs = {name: spec["direction"] for name, spec in params.items()}
    for name in joints_cfg.get("fixed", {}):
        dirs.setdefault(name, {"normal": "y", "lateral": "x", "feed": "z"}.get(_kind(name), "z"))
    lateral_face = "flank" if joints_cfg.get("lateral_face", "flanks") == "flanks" else "top"
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


def is_mesh_model(cfg: dict) -> bool:
    """Whether ``cfg`` describes a model read from a mesh file (``model: {kind: mesh}``)."""
    return (cfg.get("model") or {}).get("kind", "rig") == "mesh"


def _kind(name: str) -> str:
    return name.split("_")[1] if name.startswith("k_") else name


def build_model(cfg: dict, *, refine: int | None = None, halve: tuple[str, ...] = (), rig=None,
                progress=None) -> fem.Model:
    """Assemble the rig model described by ``cfg`` (the whole validated configuration); ``refine``
    and ``halve`` refine its mesh (see :func:`jointid.geometry.mesh.build_mesh`); ``rig`` is a geometry to use
    instead of the one built from ``cfg['rig']`` (e.g. with extra grid breakpoints).  With
    ``model: {kind: mesh}`` the model is read from the user's mesh file instead
    (:func:`jointid.fe.meshmodel.build_mesh_model`; no refinement)."""
    if is_mesh_model(cfg):
        if refine not in (None, 1) or halve:
            raise ModelError("model.kind: mesh: a mesh file is solved as it is — refinement (mesh.refine, "
                             "mesh_check, mesh.extrapolate_edges) works on the parametric rig only; "
                             "refine the mesh in the tool that made it")
        from jointid.fe.meshmodel import build_mesh_model

        return build_mesh_model(cfg, progress)
    say = progress or (lambda msg: None)
    rig_cfg, mesh_cfg = cfg["rig"], cfg["mesh"]
    rig = rig or build_rig(rig_cfg)
    rmesh = mesh_from_config(rig, mesh_cfg, refine, halve)
    basis, stiffness, M0, dof_body = assemble_solids_and_joints(cfg, rig, rmesh, mesh_cfg["element"])
    solids, solids_meta = assemble_solid_parts(cfg, rig, rmesh, basis)
    elem, intorder = basis.elem, fem.ELEMENTS[mesh_cfg["element"]][1]
    doflocs = basis.doflocs
    say(f"mesh: {rmesh.mesh.t.shape[1]} {mesh_cfg['element']} elements, {3 * basis.N} DOFs")
    S_fix = fem.facet_mass(rmesh.mesh, elem, rmesh.facets["railfix"], intorder)
    stiffness["K_railfix"] = sum(fem.spring_layer(S_fix, doflocs, i, dof_body) for i in range(3)).tocsr()
    stiffness["K_foundation"] = fem.ground_springs(
        fem.facet_mass(rmesh.mesh, elem, rmesh.facets["bottom"], intorder))
    support = rig_cfg["support"]["kind"]
    fixed = np.array([], dtype=np.int64)
    if support == "mounts":
        stiffness["K_mount"] = fem.ground_springs(
            fem.facet_mass(rmesh.mesh, elem, rmesh.facets["mount"], intorder))
    elif support == "clamped":
        sdofs = basis.get_dofs(facets=rmesh.facets["bottom"]).all()
        fixed = np.sort(np.concatenate([3 * sdofs + c for c in range(3)]))
    mass = {"M0": M0}
    for name, facets in (("motor", "motor"), ("table_top", "table_top"), ("table_edge", "table_edge")):
        mass[f"M_{name}"] = fem.surface_mass(fem.facet_mass(rmesh.mesh, elem, rmesh.facets[facets], intorder))
    pts = measuring_points(rig_cfg, rig.dims)
    xyz = pts[["x_m", "y_m", "z_m"]].to_numpy().T.copy()
    xyz[1] -= 1e-7  # nudge onto the solid side of the top surfaces
    P = basis.probes(xyz)  # (n_pts, N) scalar
    probe = fem.vector_rows(P)
    dof_part = dof_parts(basis, rmesh)
    areas = {face: float(fem.facet_mass(rmesh.mesh, elem, rmesh.facets[face], intorder).sum())
             for face in ("top", "flank", "motor", "mount")}
    meta = {"n_elements": int(rmesh.mesh.t.shape[1]), "n_dofs": int(3 * basis.N),
            "element": mesh_cfg["element"], "support": support,
            "contact_area_m2": {"top": areas["top"], "flank": areas["flank"]},
            "mount_area_m2": areas["mount"], "motor_patch_area_m2": areas["motor"],
            "motor_mass_kg": rig_cfg["motors"]["count"] * rig_cfg["motors"]["mass_each_kg"],
            "mount_area_each_m2": areas["mount"] / 4 if support == "mounts" else 0.0,
            "carriage_centres_m": rig.carriage_centres.tolist(), "dims_m": rig.dims,
            "points": pts.to_dict(orient="list"), "solids": solids_meta}
    model = fem.Model(stiffness=stiffness, mass=mass, fixed=fixed, probe=probe, doflocs=doflocs,
                      dof_part=dof_part, meta=meta, solids=solids)
    model.meta["mesh"] = {"p": rmesh.mesh.p, "t": rmesh.mesh.t, "part": rmesh.part}
    if rmesh.boxes is not None:
        lo, hi = rmesh.boxes
        T, free = localrefine.hanging_constraints(doflocs, basis.element_dofs, lo, hi, rmesh.body,
                                                  localrefine.ORDER[mesh_cfg["element"]])
        say(f"hanging nodes: {basis.N - len(free)} of {basis.N} nodes tied, {3 * len(free)} DOFs left")
        model = _constrained(model, T, free)
    return model


def assemble_solids_and_joints(cfg: dict, rig, rmesh, element: str):
    """Elasticity of the solids (materials of ``cfg``) on ``rmesh`` and the unit joint spring layers.

    Returns ``(basis, stiffness, M0, dof_body)``: ``stiffness`` holds ``K0`` and ``K_<face>_<d>`` for
    the faces ``top`` and ``flank`` (see the module docstring); ``dof_body`` is the body of each scalar
    DOF when the mesh has hanging nodes (else None).
    """
    elem_cls, intorder = fem.ELEMENTS[element]
    elem = elem_cls()
    basis = Basis(rmesh.mesh, elem, intorder=intorder)
    lam, mu, rho, _ = element_constants(cfg, rig, rmesh)
    K0, M0 = fem.assemble_elasticity(basis, lam, mu, rho)
    stiffness = {"K0": K0}
    dof_body = None
    if rmesh.boxes is not None:
        dof_body = np.empty(basis.N, np.int64)
        dof_body[basis.element_dofs] = rmesh.body[None, :]
    for face in ("top", "flank"):
        S = fem.facet_mass(rmesh.mesh, elem, rmesh.facets[face], intorder)
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


def joint_coefficients(joints_cfg: dict, theta: dict[str, float] | None = None,
                       model_cfg: dict | None = None) -> dict[str, float]:
    """Coefficient of every joint spring term (``K_top_y`` ...) at joint parameters ``theta`` (N/m^3;
    defaults: the geometric mean of the bounds for identified parameters, the configured value for
    fixed ones)."""
    values = {name: float(np.sqrt(s["lower"] * s["upper"])) for name, s in joints_cfg["parameters"].items()}
    values.update({k: float(v) for k, v in joints_cfg.get("fixed", {}).items()})
    if theta:
        values.update(theta)
    kc: dict[str, float] = {}
    for name, terms in joint_terms(joints_cfg, model_cfg).items():
        for term in terms:
            kc[term] = kc.get(term, 0.0) + values.get(name, 0.0)
    return kc


def base_coefficients(cfg: dict, model: fem.Model, theta: dict[str, float] | None = None,
                      extra_k: dict[str, float] | None = None):
    """Stiffness and mass coefficients of the rig at joint parameters ``theta``.

    ``theta`` maps joint parameter names to N/m^3 (defaults: the geometric mean of the bounds for
    identified parameters, the configured value for fixed ones).  Returns ``(k_coeffs, m_coeffs)``
    for :meth:`Model.K` and :meth:`Model.M`: the joints, the rail fixing and mounts, the motor mass
    of ``cfg`` (``M_motor``) and the solids' material ratios (:func:`solid_coefficients`, none when
    the materials are the model's own).
    """
    if is_mesh_model(cfg):
        from jointid.fe.meshmodel import mesh_constant_coefficients

        kc, mc = mesh_constant_coefficients(cfg["model"])
        for name, v in joint_coefficients(cfg["joints"], theta, cfg["model"]).items():
            kc[name] = kc.get(name, 0.0) + v
        for name, v in (extra_k or {}).items():
            kc[name] = kc.get(name, 0.0) + v
        return kc, mc
    kc = joint_coefficients(cfg["joints"], theta)
    kc["K_railfix"] = float(cfg["rig"]["rails"].get("fixing_stiffness_N_per_m3", RAIL_BONDED_N_PER_M3))
    if "K_mount" in model.stiffness:
        kc["K_mount"] = cfg["rig"]["support"]["k_mount_N_per_m"] / model.meta["mount_area_each_m2"]
    for name, v in (extra_k or {}).items():
        kc[name] = kc.get(name, 0.0) + v
    mc = {"M_motor": motor_mass_kg(cfg)}
    ks, ms = solid_coefficients(cfg, model)
    kc.update(ks)
    mc.update(ms)
    return kc, mc



# ---------------------------------------------------------------- cache
def save_model(model: fem.Model, path: str | Path) -> None:
    """Write the model to one ``.npz`` file atomically (temporary file + rename)."""
    path = Path(path)
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
    write_npz_mappable(path, arrays)


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
