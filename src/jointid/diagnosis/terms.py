"""The system of terms of the diagnosis model: the affine FE terms the effects act on.

The system of terms (:class:`System`)
------------------------------------
``build_system(model, spec)`` derives from a built model:

* the joint layers split per carriage: ``K_top_y@0 .. K_top_y@3`` (carriage numbers follow
  ``model.meta['carriage_centres_m']``), so a per-carriage contact pressure can scale each block;
* a clamped base bottom turned into a bonded spring layer to the ground, ``K_foundation`` at
  1e15 N/m^3 (the value standing in for a bonded rail fixing, ``model.RAIL_BONDED_N_PER_M3``), so the
  base support can be softened continuously; the bonded layer reproduces the clamped frequencies to
  better than 1e-4 (checked in ``tests/test_effects.py``);
* the solids at the configuration's materials: where they differ from the model's own (a hypothesis
  with a steel table on the run's model), the parts' solid terms join the system as terms of their
  own (``K_solid_<part>``, ``M_solid_<part>``, and ``K_lambda_<part>`` for another Poisson's ratio,
  :mod:`jointid.fe.lame`) with their coefficients (:func:`jointid.fe.model.solid_coefficients`).
  ``K0`` and ``M0`` stay the model's, so a reduced basis of the run's model serves the system too:
  it only projects the added terms (:func:`jointid.fe.warmstart.load`).

See docs/effects.md; the effects themselves are in :mod:`jointid.diagnosis.effects`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
import scipy.sparse as sp

from jointid.errors import ModelError
from jointid.fe.affine import sequential_sum
from jointid.fe.fem import Model
from jointid.config.typed import ModelSpec
from jointid.fe.lame import add_lame_terms
from jointid.fe.model import (JOINT_FACES, RAIL_BONDED_N_PER_M3, base_coefficients, joint_layer_terms,
                              motor_mass_kg, solid_coefficients)
from jointid.geometry.points import dof_labels
from jointid.geometry.rig import PART_IDS

__all__ = ["BONDED_N_PER_M3", "JOINT_FACES", "StateInfo", "System", "baseline_coefficients", "build_system",
           "build_systems", "carried_mass_kg"]

BONDED_N_PER_M3 = RAIL_BONDED_N_PER_M3


# ------------------------------------------------------------------ system of terms
@dataclass
class StateInfo:
    """Operating state as the effects see it: name and vertical motor attraction (N)."""

    name: str
    em_force_N: float = 0.0


@dataclass
class System:
    """Affine terms of the diagnosis model (joint layers split per carriage, penalty support).

    Attributes
    ----------
    stiffness, mass : dict of name -> CSR (n_dofs, n_dofs)
        ``K0``/``M0`` plus affine terms; joint layers as ``K_<face>_<d>@<carriage>``.
    fixed : ndarray
        Constrained DOFs (empty when the clamped support is a bonded spring layer).
    probe : CSR (3 * n_points, n_dofs)
        Displacements at the measuring points, rows (point, direction).
    labels : list of str
        ``"<point>:<direction>"`` per probe row.
    carriage_xz_m : ndarray (n_carriages, 2)
        Carriage centres (X, Z) in m.
    carried_mass_kg : float
        Mass resting on the joints (table + carriages + motors), kg.
    support : str
        ``rig.support.kind`` of the model.
    model : Model
        The model the system was built from.
    """

    stiffness: dict
    mass: dict
    fixed: np.ndarray
    probe: sp.csr_matrix
    labels: list
    carriage_xz_m: np.ndarray
    carried_mass_kg: float
    support: str
    model: Model
    meta: dict = field(default_factory=dict)
    layers: frozenset = frozenset()  # the joint-layer terms split per carriage (unsplit names)

    @property
    def n_dofs(self) -> int:
        """Number of DOFs of the model."""
        return self.stiffness["K0"].shape[0]

    @property
    def n_carriages(self) -> int:
        """Number of carriages."""
        return len(self.carriage_xz_m)

    @property
    def ordering(self):
        """The model's cached fill-reducing ordering when the free DOFs are the model's."""
        same = np.array_equal(np.asarray(self.fixed), np.asarray(self.model.fixed))
        return self.model.ordering if same else None

    def K(self, kc: dict) -> sp.csr_matrix:
        """``K0 + sum kc[name] * stiffness[name]`` (CSR), the terms added in the order of ``kc``
        (:func:`jointid.fe.affine.sequential_sum`)."""
        return sequential_sum(self.stiffness["K0"], [(c, self.stiffness[n]) for n, c in kc.items() if c != 0.0])

    def M(self, mc: dict) -> sp.csr_matrix:
        """``M0 + sum mc[name] * mass[name]`` (CSR), the terms added in the order of ``mc``."""
        return sequential_sum(self.mass["M0"], [(c, self.mass[n]) for n, c in mc.items() if c != 0.0])


def carried_mass_kg(model: Model, M0=None, motor_kg: float | None = None) -> float:
    """Mass resting on the carriage joints: table + carriages (from ``M0``) + motor primaries, kg.

    The body formed by the table and the carriages shares no node with the rails or the base (the
    joints are spring layers between duplicated nodes), so the row sums of ``M0`` over its nodes add
    up to its mass (partition of unity).  Nodes on the carriage/table interface are owned by both
    parts (``dof_part == -1``) and counted with the body.  ``M0`` and ``motor_kg`` replace the
    model's own (a configuration with other densities or motors on this model, :func:`build_system`).
    A model read from a mesh file carries the number itself (``meta['carried_mass_kg']``,
    :mod:`jointid.fe.meshmodel`).
    """
    if "carried_mass_kg" in model.meta:
        return float(model.meta["carried_mass_kg"])
    part = model.dof_part
    body = np.isin(part, [PART_IDS["carriage"], PART_IDS["table"]]) | (part < 0)
    M0 = model.mass["M0"] if M0 is None else M0
    ey = np.zeros(M0.shape[0])
    ey[1::3] = 1.0
    rows = 3 * np.flatnonzero(body) + 1
    motors = model.meta.get("motor_mass_kg", 0.0) if motor_kg is None else motor_kg
    return float((M0 @ ey)[rows].sum() + motors)


def _split_by_carriage(A: sp.csr_matrix, owner: np.ndarray, n: int) -> list[sp.csr_matrix]:
    """Split a joint layer into per-carriage parts by the owner of each (vector) DOF."""
    C = A.tocoo()
    orow, ocol = owner[C.row], owner[C.col]
    if np.any(orow != ocol):
        raise ModelError("joint layer couples DOFs of two carriages — the carriages overlap; check "
                         "rig.carriages.pitch_m and length_m")
    out = []
    for c in range(n):
        sel = orow == c
        out.append(sp.csr_matrix((C.data[sel], (C.row[sel], C.col[sel])), shape=A.shape))
    return out


def term_component(name: str) -> str:
    """Direction or component of a layer term, ``K_top_y@2`` -> ``y``, ``K_guide_1_normal`` -> ``normal``."""
    return name.split("@")[0].rsplit("_", 1)[1]


def build_system(model: Model, spec: ModelSpec) -> System:
    """Diagnosis system of ``model``: joint terms per carriage and the clamped support as springs.

    Parameters
    ----------
    model : Model
        Built or loaded model (``model.build_model`` / ``model.load_model``).
    spec : ModelSpec
        The configuration's model (its materials; ``rig.support.kind`` where the model does not say).
    """
    centres = np.asarray(model.meta["carriage_centres_m"], float)
    xz = centres[:, [0, 2]]
    loc = model.doflocs[[0, 2]].T  # (n_scalar, 2)
    d2 = ((loc[:, None, :] - xz[None, :, :]) ** 2).sum(axis=2)
    owner = np.repeat(np.argmin(d2, axis=1), 3)
    add_lame_terms(spec, model)  # a part of another Poisson's ratio: its volumetric term
    ks, ms = solid_coefficients(spec, model)  # the configuration's materials against the model's
    stiffness = {"K0": model.stiffness["K0"]}
    layers = joint_layer_terms(model)
    for name, A in model.stiffness.items():
        if name in layers:
            for c, part in enumerate(_split_by_carriage(A, owner, len(xz))):
                stiffness[f"{name}@{c}"] = part
        elif name != "K0":
            stiffness[name] = A
    support = model.meta.get("support") or spec.rig.support_kind
    fixed = np.asarray(model.fixed, dtype=np.int64)
    if support == "clamped":
        fixed = np.array([], dtype=np.int64)  # bonded foundation layer instead (see module doc)
    stiffness.update({name: model.solid_term(name) for name in ks})
    pts = pd.DataFrame(model.meta["points"])
    mass = {**model.mass, **{name: model.solid_term(name) for name in ms}}
    motors = None if spec.is_mesh_file else motor_mass_kg(spec.rig)
    M0 = model.M(ms) if ms else model.mass["M0"]  # at the configuration's densities
    return System(stiffness=stiffness, mass=mass, fixed=fixed, probe=model.probe,
                  labels=dof_labels(pts), carriage_xz_m=xz, carried_mass_kg=carried_mass_kg(model, M0, motors),
                  support=support, model=model, meta={"points": pts}, layers=layers)


def build_systems(model: Model, specs: list[ModelSpec]) -> list[System]:
    """The systems of several configurations on one model (hypotheses that change only coefficients of it,
    :func:`jointid.config.hypotheses.needs_own_model`): each is :func:`build_system`'s, except that all share
    one set of terms, the union of what each needs.  A term a configuration does not use has no coefficient
    in it, so its ``K`` and ``M`` are those of its own system; and one reduced solver serves them all (it
    needs the same term dicts, :class:`jointid.diagnosis.fitting.Diagnoser`).  Each keeps its carried mass."""
    systems = [build_system(model, spec) for spec in specs]
    stiffness, mass = dict(systems[0].stiffness), dict(systems[0].mass)
    for s in systems[1:]:
        for name, A in s.stiffness.items():
            stiffness.setdefault(name, A)
        for name, A in s.mass.items():
            mass.setdefault(name, A)
    return [replace(s, stiffness=stiffness, mass=mass) for s in systems]


def baseline_coefficients(system: System, spec: ModelSpec, theta: dict | None = None) -> tuple[dict, dict]:
    """Term coefficients of the baseline (no effect) at joint parameters ``theta`` (N/m^3), for the
    model ``spec`` (:class:`jointid.config.typed.ModelSpec`, built once by the caller).

    Joint terms are expanded to every carriage with the same value; a clamped support becomes the
    bonded foundation layer.  Returns ``(kc, mc)`` for :meth:`System.K` / :meth:`System.M`.
    """
    kc0, mc = base_coefficients(spec, system.model, theta)
    kc = {}
    for name, v in kc0.items():
        if name in system.layers:
            for c in range(system.n_carriages):
                kc[f"{name}@{c}"] = float(v)
        else:
            kc[name] = float(v)
    if system.support == "clamped":
        kc["K_foundation"] = BONDED_N_PER_M3
    return kc, dict(mc)
