"""Rigidity of one carriage on its rail as a catalogue states it, from the identified joint springs.

A catalogue quotes a block's rigidity as load over the block's deflection relative to the rail, with
the rail on a rigid bed and the block under a rigid mounting plate.  The joint springs identified by
this project (N/m^3 on the contact faces) are only part of that: the block's skirts and the rail's head
deform in series with them.  To compare like with like, this module runs that test on the model's own
parts: one carriage of the rig on a rail segment (the rig's cross-sections, materials and contact faces,
and the joint spring layers at the given parameters), the rail's bottom clamped, the carriage's top
face moved as a rigid plate by a unit displacement along X (lateral), Y (normal) or Z (feed).  The
reaction force over the displacement is the rigidity.  The same test with stiff joints (every joint
spring 1e4 times stiffer) gives the parts' own rigidity, which the springs act in series with.

The model is its own small mesh (``cell_m`` cells, quadratic hexahedra), independent of the rig's mesh.
:func:`catalogue_comparison` holds the result against the preload classes of the guide's catalogue
(config section ``catalogue``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from jointid.config.typed import ModelSpec
from jointid.errors import ModelError
from jointid.geometry.mesh import build_mesh
from jointid.fe.model import assemble_solids_and_joints, dof_parts, joint_coefficients
from jointid.fe.modal import factorize
from jointid.geometry.rig import Box, Rig

DIRECTIONS = {"lateral": 0, "normal": 1, "feed": 2}
STIFF_JOINTS = 1.0e4  # factor on every joint spring for "the parts alone"


@dataclass(frozen=True)
class BlockRigidity:
    """Rigidity of one carriage on its rail, N/m per direction (``lateral``, ``normal``, ``feed``)."""

    assembly_N_per_m: dict   # joint springs and parts in series: the catalogue's quantity
    parts_N_per_m: dict      # the same test with stiff joints: carriage and rail alone
    n_dofs: int
    cell_m: float

    def per_um(self, which: str = "assembly") -> dict:
        """``{direction: N/um}`` of the assembly or the parts."""
        src = self.assembly_N_per_m if which == "assembly" else self.parts_N_per_m
        return {d: v * 1e-6 for d, v in src.items()}


def block_rig(geometry: Mapping, overhang_m: float | None = None) -> Rig:
    """One carriage on a rail segment, the rail's bottom at Y = 0 and the carriage centred at Z = 0.

    ``geometry``: the ``rig`` section (:attr:`jointid.config.typed.RigModel.geometry`), its rails and carriages.
    The segment sticks out of the carriage by ``overhang_m`` at either end (default: twice the rail
    height, where the rail's deflection under the carriage has decayed)."""
    r, c = geometry["rails"], geometry["carriages"]
    rh, gc, fh = r["height_m"], c["ground_clearance_m"], c["flank_contact_height_m"]
    w, W, L, ch = r["width_m"], c["width_m"], c["length_m"], c["height_m"]
    if not (gc < rh - fh and fh > 0 and ch > rh and W > w):
        raise ModelError("rig.carriages: the carriage must wrap the rail (ground_clearance_m < rail height - "
                         "flank_contact_height_m, height_m > rail height, width_m > rail width)")
    over = 2 * rh if overhang_m is None else overhang_m
    Lr = L + 2 * over
    boxes = [Box("rail", (-w / 2, 0.0, -Lr / 2), (w / 2, rh, Lr / 2)),
             Box("carriage", (-W / 2, gc, -L / 2), (W / 2, ch, L / 2))]
    contact = {"top": [Box("top", (-w / 2, rh, -L / 2), (w / 2, rh, L / 2))],
               "flank": [Box("flank", (x, rh - fh, -L / 2), (x, rh, L / 2)) for x in (-w / 2, w / 2)]}
    xs = np.array(sorted({-W / 2, -w / 2, w / 2, W / 2}))
    ys = np.array(sorted({0.0, gc, rh - fh, rh, ch}))
    zs = np.array(sorted({-Lr / 2, -L / 2, L / 2, Lr / 2}))
    return Rig(boxes=boxes, contact=contact, patches={}, carriage_centres=np.array([[0.0, rh, 0.0]]),
               breakpoints=(xs, ys, zs), materials={"rail": r["material"], "carriage": c["material"]},
               dims={"rail_top_m": rh, "carriage_top_m": ch})


class BlockTest:
    """The catalogue test of :func:`block_rig`, meshed and assembled once for any joint parameters.

    ``spec`` is the model's description (rig, materials, joints, mesh element, solver backend);
    ``cell_m``: the cell edge of the test's own mesh, m; ``element`` and ``backend`` override ``spec``'s.
    """

    def __init__(self, spec: ModelSpec, cell_m: float = 0.006, element: str | None = None,
                 backend: str | None = None):
        rig = block_rig(spec.rig.geometry)
        rmesh = build_mesh(rig, cell_m)
        basis, self.stiffness, _, _ = assemble_solids_and_joints(spec.materials, rig, rmesh,
                                                                 element or spec.mesh.element)
        y, part = basis.doflocs[1], dof_parts(basis, rmesh)
        rail_bottom = np.flatnonzero((part == 1) & (np.abs(y) < 1e-9))
        self.plate = np.flatnonzero((part == 2) & (np.abs(y - rig.dims["carriage_top_m"]) < 1e-9))
        self.n = 3 * basis.N
        self.moved = np.concatenate([3 * self.plate + c for c in range(3)])
        self.free = np.setdiff1d(np.arange(self.n),
                                 np.concatenate([3 * rail_bottom + c for c in range(3)] + [self.moved]))
        self.joints, self.cell_m = spec.joints, float(cell_m)
        self.backend = backend or spec.solver.backend
        self._ordering = None  # the first factorisation's fill-reducing ordering: every test has the same pattern

    def rigidity(self, theta: dict[str, float], parts: bool = True) -> BlockRigidity:
        """Rigidity at joint parameters ``theta`` (N/m^3); ``parts=False`` skips the stiff-joint test
        (``parts_N_per_m`` is then empty)."""
        kc = joint_coefficients(self.joints, theta)
        out = {}
        for label, scale in (("assembly", 1.0), ("parts", STIFF_JOINTS))[: 2 if parts else 1]:
            K = (self.stiffness["K0"] + sum((scale * v) * self.stiffness[t] for t, v in kc.items())).tocsr()
            lu = factorize(K[self.free][:, self.free], self.backend, self._ordering)
            self._ordering = getattr(lu, "ordering", None)  # PARDISO's (the same bits, without its reordering step)
            Kfm = K[self.free][:, self.moved]
            res = {}
            for name, d in DIRECTIONS.items():
                u = np.zeros(self.n)
                u[3 * self.plate + d] = 1.0  # the rigid plate moved by 1 m along d, clamped otherwise
                u[self.free] = -lu.solve(Kfm @ u[self.moved])
                res[name] = float((K @ u)[3 * self.plate + d].sum())  # reaction on the plate, N
            out[label] = res
        return BlockRigidity(assembly_N_per_m=out["assembly"], parts_N_per_m=out.get("parts", {}),
                             n_dofs=int(self.n), cell_m=self.cell_m)


def block_rigidity(spec: ModelSpec, theta: dict[str, float], cell_m: float = 0.006, element: str | None = None,
                   backend: str | None = None, parts: bool = True) -> BlockRigidity:
    """Catalogue-style rigidity of one carriage on its rail at joint parameters ``theta`` (N/m^3):
    :class:`BlockTest` for one parameter point (``cell_m``: its mesh's cell edge, m)."""
    return BlockTest(spec, cell_m, element, backend).rigidity(theta, parts)


# ------------------------------------------------------------------------------ against the catalogue
CATALOGUE_KEYS = {"normal": "normal_N_per_um", "lateral": "lateral_N_per_um"}
"""Directions a guide catalogue states a block's rigidity in, and the key of each in ``catalogue.classes``."""


def catalogue_comparison(identified: dict[str, dict], catalogue: dict | None) -> dict | None:
    """A carriage's rigidity held against each preload class of its guide's catalogue.

    Parameters
    ----------
    identified : {direction: dict}
        Per direction (``normal``, ``lateral``; others are ignored) the carriage on its rail in N/um:
        ``assembly_N_per_um`` and, optionally, ``assembly_ci95_low_N_per_um`` / ``..._high_...``
        (as in ``carriage_rigidity.json``).
    catalogue : dict or None
        The config section ``catalogue`` (``block``, ``source``, ``classes: {name: {normal_N_per_um,
        lateral_N_per_um (optional), description}}``).

    Returns
    -------
    dict or None
        None without classes.  Otherwise, per direction: the identified value, per class the
        catalogue's value and ``ratio`` = identified / catalogue, the ``nearest_class`` (smallest
        |log ratio|: nearest as a factor, so 2x above and 2x below are equally far), the softest and
        stiffest class, ``exceeds_stiffest`` / ``below_softest`` (the value) and
        ``interval_exceeds_stiffest`` / ``interval_below_softest`` (the whole 95 % interval, when
        given); and ``lateral_to_normal`` of the identification and of every class.  A class without
        ``lateral_N_per_um`` is compared laterally with its ``normal_N_per_um``
        (``catalogue_key`` says which value was used).
    """
    classes = (catalogue or {}).get("classes") or {}
    if not classes:
        return None
    out = {"block": catalogue.get("block", ""), "source": catalogue.get("source", ""),
           "compared": "carriage on its rail (assembly_N_per_um) against one block as catalogued",
           "directions": {}}
    for d, key in CATALOGUE_KEYS.items():
        r = identified.get(d)
        if r is None:
            continue
        value = float(r["assembly_N_per_um"])
        rows = {}
        for name, c in classes.items():
            used = key if c.get(key) is not None else "normal_N_per_um"
            cat = float(c[used])
            rows[name] = {"catalogue_N_per_um": cat, "catalogue_key": used, "ratio": value / cat}
        by_value = sorted(rows, key=lambda n: rows[n]["catalogue_N_per_um"])
        softest, stiffest = by_value[0], by_value[-1]
        lo, hi = r.get("assembly_ci95_low_N_per_um"), r.get("assembly_ci95_high_N_per_um")
        doc = {"identified_N_per_um": value, "classes": rows,
               "nearest_class": min(rows, key=lambda n: abs(math.log(rows[n]["ratio"]))),
               "softest_class": softest, "stiffest_class": stiffest,
               "exceeds_stiffest": value > rows[stiffest]["catalogue_N_per_um"],
               "below_softest": value < rows[softest]["catalogue_N_per_um"]}
        if lo is not None and hi is not None:
            doc.update({"identified_ci95_low_N_per_um": float(lo), "identified_ci95_high_N_per_um": float(hi),
                        "interval_exceeds_stiffest": float(lo) > rows[stiffest]["catalogue_N_per_um"],
                        "interval_below_softest": float(hi) < rows[softest]["catalogue_N_per_um"]})
        out["directions"][d] = doc
    dirs = out["directions"]
    if "normal" in dirs and "lateral" in dirs:
        out["lateral_to_normal"] = {
            "identified": dirs["lateral"]["identified_N_per_um"] / dirs["normal"]["identified_N_per_um"],
            "catalogue": {n: dirs["lateral"]["classes"][n]["catalogue_N_per_um"]
                          / dirs["normal"]["classes"][n]["catalogue_N_per_um"] for n in classes}}
    return out


def catalogue_verdict(direction: str, doc: dict) -> str:
    """One line on one direction of :func:`catalogue_comparison`, e.g. 'normal 1,370 N/um: 1.88 x ZB
    (730), above the stiffest class'."""
    near, stiff, soft = doc["nearest_class"], doc["stiffest_class"], doc["softest_class"]
    c = doc["classes"]
    text = f"{direction} {doc['identified_N_per_um']:,.0f} N/um: "
    if doc["exceeds_stiffest"]:
        text += (f"{c[stiff]['ratio']:.2f} x {stiff} ({c[stiff]['catalogue_N_per_um']:,.0f}), above the stiffest class"
                 + (" with its whole 95 % interval" if doc.get("interval_exceeds_stiffest") else ""))
    elif doc["below_softest"]:
        text += (f"{c[soft]['ratio']:.2f} x {soft} ({c[soft]['catalogue_N_per_um']:,.0f}), below the softest class"
                 + (" with its whole 95 % interval" if doc.get("interval_below_softest") else ""))
    else:
        text += f"within the classes, nearest {near} ({c[near]['catalogue_N_per_um']:,.0f}, ratio {c[near]['ratio']:.2f})"
    return text
