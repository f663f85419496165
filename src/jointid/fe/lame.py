"""A part's Poisson's ratio as a coefficient of a built model: the Lamé split of its elasticity.

A part's elasticity is ``K_b = lambda_b A_b + mu_b B_b`` (``A_b``: the volumetric form
``int div u div v``, ``B_b``: ``int 2 eps(u) : eps(v)``).  The model keeps ``K_solid_b`` at the part's
reference material (``lambda_0, mu_0``).  With ``K_lambda_b = lambda_0 A_b`` (the volumetric share of
``K_solid_b``),

    K_b(lambda, mu) = (mu / mu_0) K_solid_b + (lambda / lambda_0 - mu / mu_0) K_lambda_b,

so a new material of any Poisson's ratio is two coefficients, ``mu / mu_0 - 1`` on ``K_solid_b`` and
``lambda / lambda_0 - mu / mu_0`` on ``K_lambda_b`` (zero when only Young's modulus changes: then
``lambda / lambda_0 = mu / mu_0 = E / E_0``).  The model file does not keep ``K_lambda_b`` (it would
add a quarter to its size for a rarely used term): :func:`add_lame_terms` assembles it for the parts
that need it, from the rig's mesh rebuilt from the configuration (about 1 s on the default mesh), and
checks that this mesh is the model's own.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from skfem import Basis

from jointid.config.typed import ModelSpec
from jointid.errors import ModelError
from jointid.fe import fem
from jointid.geometry import localrefine
from jointid.geometry.mesh import mesh_from_config
from jointid.geometry.rig import PART_IDS, build_rig


def poisson_changed_parts(spec: ModelSpec, model: fem.Model) -> list[str]:
    """Parts whose Poisson's ratio in ``spec`` differs from the one ``model`` was built with."""
    if spec.is_mesh_file:
        return []
    parts = (model.meta.get("solids") or {}).get("parts") or {}
    return [part for part, ref in parts.items()
            if float(spec.materials[spec.rig.part_materials[part]].poisson_ratio) != ref["poisson_ratio"]]


def add_lame_terms(spec: ModelSpec, model: fem.Model, progress=None) -> list[str]:
    """Assemble ``K_lambda_<part>`` into ``model.solids`` (in memory) for every part whose Poisson's
    ratio ``spec`` changes, so that :func:`jointid.fe.solids.solid_coefficients` can express the
    change.  Returns the names added.  :class:`ModelError` when the rig's mesh rebuilt from ``spec``
    is not the model's (another mesh, geometry or refinement)."""
    parts = [p for p in poisson_changed_parts(spec, model) if f"K_lambda_{p}" not in model.solids]
    if not parts:
        return []
    say = progress or (lambda msg: None)
    rig = build_rig(spec.rig.geometry)
    rmesh = mesh_from_config(rig, spec.mesh)
    stored = model.meta.get("mesh") or {}
    if not (np.array_equal(np.asarray(stored.get("p")), rmesh.mesh.p)
            and np.array_equal(np.asarray(stored.get("t")), rmesh.mesh.t)):
        raise ModelError(f"rig.*.material: a change of Poisson's ratio ({', '.join(parts)}) needs the model's mesh, "
                         "and the mesh of this configuration is not the model's — build a model of this "
                         "configuration (results/model/matrices.npz from the same rig and mesh sections)")
    elem_cls, intorder = fem.ELEMENTS[spec.mesh.element]
    basis = Basis(rmesh.mesh, elem_cls(), intorder=intorder)
    refs = model.meta["solids"]["parts"]
    zeros = np.zeros(len(rmesh.part))
    Tv = None
    if rmesh.boxes is not None:
        lo, hi = rmesh.boxes
        T, _ = localrefine.hanging_constraints(basis.doflocs, basis.element_dofs, lo, hi, rmesh.body,
                                               localrefine.ORDER[spec.mesh.element])
        Tv = sp.kron(T, sp.eye(3), format="csr")
    names = []
    for part in parts:
        sel = np.flatnonzero(rmesh.part == PART_IDS[part])
        lam0 = fem.lame(refs[part]["youngs_modulus_Pa"], refs[part]["poisson_ratio"])[0]
        K, _ = fem.assemble_elasticity(basis, np.full(len(zeros), lam0), zeros, zeros, elements=sel)
        if Tv is not None:
            K = Tv.T @ K @ Tv
        if K.shape != (model.n_dofs, model.n_dofs):
            raise ModelError(f"the volumetric term of part {part} has {K.shape[0]} DOFs, the model {model.n_dofs} "
                             "— build a model of this configuration")
        model.solids[f"K_lambda_{part}"] = K.tocsr()
        names.append(f"K_lambda_{part}")
    say(f"model: volumetric terms {', '.join(names)} assembled for a change of Poisson's ratio")
    return names
