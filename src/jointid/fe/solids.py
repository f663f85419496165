"""The solids of the rig per part: each part's elasticity and mass as terms of the affine model.

``K0 = sum_b K_solid_b`` and ``M0 = sum_b M_solid_b`` over the parts of
:data:`jointid.geometry.rig.PART_IDS`; a part's Young's modulus and density are then coefficients
(``E_b / E_b,ref - 1``, ``rho_b / rho_b,ref - 1``) of the model built at the reference materials, and
so is the motor mass (``M_motor``).  :func:`jointid.fe.model.build_model` keeps the terms
(``Model.solids``; the file layout is described there).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from jointid.config.typed import PART_SECTIONS, Material, ModelSpec, RigModel
from jointid.errors import ModelError
from jointid.fe import fem
from jointid.geometry.rig import PART_IDS

def is_solid_term(name: str) -> bool:
    """Whether the term ``name`` belongs to the solids: ``K0``, ``M0`` and each part's ``K_solid_<part>``,
    ``M_solid_<part>``, ``K_lambda_<part>`` (a discretised continuum, whose stiffness the mesh's refinement
    changes); every other term is a spring layer or an added mass."""
    return name in ("K0", "M0") or "_solid_" in name or name.startswith("K_lambda_")


def element_constants(materials: Mapping[str, Material], rig, rmesh):
    """Lamé constants and density of every element (Pa, kg/m^3) from ``materials`` (by name), and
    the reference material of every part present: ``{part: {material, youngs_modulus_Pa,
    poisson_ratio, density_kg_per_m3}}``."""
    inv_parts = {v: k for k, v in PART_IDS.items()}
    lam, mu, rho = (np.empty(len(rmesh.part)) for _ in range(3))
    ref = {}
    for pid in np.unique(rmesh.part):
        name = rig.materials[inv_parts[pid]]
        m = materials[name]
        sel = rmesh.part == pid
        lam[sel], mu[sel] = fem.lame(m.youngs_modulus_Pa, m.poisson_ratio)
        rho[sel] = m.density_kg_per_m3
        ref[inv_parts[pid]] = {"material": name, **{k: float(getattr(m, k)) for k in
                                                    ("youngs_modulus_Pa", "poisson_ratio", "density_kg_per_m3")}}
    return lam, mu, rho, ref


def assemble_solid_parts(materials: Mapping[str, Material], rig, rmesh, basis) -> tuple[dict, dict]:
    """The solids per part, ``K_solid_<part>`` and ``M_solid_<part>`` at ``materials`` (by name),
    for every part but the one with the most elements (the complement, formed from ``K0`` and ``M0``
    when asked, :meth:`jointid.fe.fem.Model.solid_term`).  Returns ``(terms, meta)``, meta
    ``{"parts": reference materials (:func:`element_constants`), "complement": part}``."""
    lam, mu, rho, ref = element_constants(materials, rig, rmesh)
    count = {p: int(np.count_nonzero(rmesh.part == PART_IDS[p])) for p in ref}
    complement = max(count, key=lambda p: (count[p], p))
    terms = {}
    for part in ref:
        if part != complement:
            K, M = fem.assemble_elasticity(basis, lam, mu, rho, elements=np.flatnonzero(rmesh.part == PART_IDS[part]))
            terms[f"K_solid_{part}"], terms[f"M_solid_{part}"] = K, M
    return terms, {"parts": ref, "complement": complement}


def solid_coefficients(spec: ModelSpec, model: fem.Model) -> tuple[dict[str, float], dict[str, float]]:
    """Coefficients of the solid terms at the rig's materials of ``spec``: ``K_solid_<part>``:
    ``E / E_ref - 1`` and ``M_solid_<part>``: ``rho / rho_ref - 1``, the reference being the material
    the model was built with (``model.meta['solids']``); only the non-zero ones (none at the
    reference).  A part of another Poisson's ratio takes the Lamé split of :mod:`jointid.fe.lame`
    (``K_solid_<part>``: ``mu / mu_ref - 1``, ``K_lambda_<part>``: ``lambda / lambda_ref - mu / mu_ref``)
    when the model holds its volumetric term (:func:`jointid.fe.lame.add_lame_terms`), else
    :class:`ModelError`.  A model without solid terms (a mesh file's, or one written before them)
    gives none."""
    kc: dict[str, float] = {}
    mc: dict[str, float] = {}
    if spec.is_mesh_file:
        return kc, mc
    parts = (model.meta.get("solids") or {}).get("parts") or {}
    for part, section in PART_SECTIONS.items():
        if part not in parts:
            continue
        name = spec.rig.part_materials[part]
        m = spec.materials[name]
        r = parts[part]
        c = float(m.youngs_modulus_Pa) / r["youngs_modulus_Pa"] - 1.0
        if float(m.poisson_ratio) != r["poisson_ratio"]:
            if f"K_lambda_{part}" not in model.solids:
                raise ModelError(f"rig.{section}.material: {name} has Poisson's ratio {m.poisson_ratio:g}, the "
                                 f"model was built with {r['poisson_ratio']:g} ({r['material']}) — its volumetric "
                                 "term is not assembled (jointid.fe.lame.add_lame_terms), or build a model of "
                                 "this configuration")
            lam, mu = fem.lame(float(m.youngs_modulus_Pa), float(m.poisson_ratio))
            lam0, mu0 = fem.lame(r["youngs_modulus_Pa"], r["poisson_ratio"])
            c = mu / mu0 - 1.0
            kc[f"K_lambda_{part}"] = lam / lam0 - mu / mu0
        d = float(m.density_kg_per_m3) / r["density_kg_per_m3"] - 1.0
        if c != 0.0:
            kc[f"K_solid_{part}"] = c
        if d != 0.0:
            mc[f"M_solid_{part}"] = d
    return kc, mc


def motor_mass_kg(rig: RigModel) -> float:
    """The motor primaries' mass on the table of ``rig``, kg (count x mass each): the
    coefficient of ``M_motor`` (a 1 kg layer), so a changed motor mass needs no model of its own."""
    return float(rig.motor_mass_kg)
