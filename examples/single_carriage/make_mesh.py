"""Mesh of the second example: one carriage with a small table on a short rail bolted to a plate.

The carriage wraps the rail: it touches the rail top (joint ``top``) and the rail's sides below it
(joint ``flank``).

Run with gmsh's Python API (``pip install -e ".[mesh]"``) from the repository root:

    python examples/single_carriage/make_mesh.py

It writes ``examples/single_carriage/stage.msh`` (quadratic tetrahedra, gmsh 2.2 with physical
names).  Plate and rail are fused (they share nodes: bonded), carriage and table are fused; the two
pairs are meshed on their own, so the carriage bottom and the rail top are two coincident surfaces
with different meshes, joined by the joint layer.  Axes: X lateral, Y up, Z feed (along the rail).
"""

from __future__ import annotations

import sys
from pathlib import Path

import gmsh

HERE = Path(__file__).resolve().parent
# m: (x0, y0, z0, dx, dy, dz)
PLATE = (-0.15, 0.0, -0.20, 0.30, 0.03, 0.40)
RAIL = (-0.0115, 0.03, -0.20, 0.023, 0.022, 0.40)
CARRIAGE = (-0.024, 0.036, -0.042, 0.048, 0.046, 0.084)  # minus the rail's slot
TABLE = (-0.08, 0.082, -0.08, 0.16, 0.020, 0.16)
SIZE_M = 0.03  # largest element edge
SIZE_JOINT_M = 0.008  # element edge on and near the joint


def _faces_at(volumes, axis: int, value: float, inside=None):
    """Boundary surfaces of ``volumes`` lying in the plane ``x[axis] = value`` (and whose centre
    satisfies ``inside``)."""
    out = []
    for dim, tag in gmsh.model.getBoundary([(3, v) for v in volumes], oriented=False, combined=False):
        lo = gmsh.model.getBoundingBox(dim, tag)
        if abs(lo[axis] - value) < 1e-6 and abs(lo[axis + 3] - value) < 1e-6:
            c = [(lo[i] + lo[i + 3]) / 2 for i in range(3)]
            if inside is None or inside(c):
                out.append(tag)
    return sorted(set(out))


def build(path: Path = HERE / "stage.msh") -> Path:
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("single_carriage")
    occ = gmsh.model.occ
    plate, rail = occ.addBox(*PLATE), occ.addBox(*RAIL)
    block, table = occ.addBox(*CARRIAGE), occ.addBox(*TABLE)
    slot = occ.addBox(RAIL[0], CARRIAGE[1] - 0.001, CARRIAGE[2] - 0.001, RAIL[3], RAIL[1] + RAIL[4] - CARRIAGE[1] + 0.001,
                      CARRIAGE[5] + 0.002)
    (cut, _) = occ.cut([(3, block)], [(3, slot)])
    carriage = cut[0][1]
    # bond plate + rail and carriage + table; the carriage and the rail stay apart (the joint)
    (lower, lmap), (upper, umap) = occ.fragment([(3, plate)], [(3, rail)]), occ.fragment([(3, carriage)], [(3, table)])
    occ.synchronize()
    plate_v, rail_v = lmap[0][0][1], lmap[1][0][1]
    carriage_v, table_v = umap[0][0][1], umap[1][0][1]
    y_rail_top, y_table_top = RAIL[1] + RAIL[4], TABLE[1] + TABLE[4]
    x_side = RAIL[0] + RAIL[3]
    groups2 = {
        "rail_top": _faces_at([rail_v], 1, y_rail_top),
        "rail_sides": _faces_at([rail_v], 0, -x_side) + _faces_at([rail_v], 0, x_side),
        "carriage_top_contact": _faces_at([carriage_v], 1, y_rail_top),
        "carriage_flanks": _faces_at([carriage_v], 0, -x_side) + _faces_at([carriage_v], 0, x_side),
        "plate_bottom": _faces_at([plate_v], 1, 0.0),
        "table_top": _faces_at([table_v], 1, y_table_top),
    }
    for name, tags in groups2.items():
        if not tags:
            sys.exit(f"make_mesh: no surface found for {name}")
        gmsh.model.addPhysicalGroup(2, tags, name=name)
    for name, tag in (("plate", plate_v), ("rail", rail_v), ("carriage", carriage_v), ("table", table_v)):
        gmsh.model.addPhysicalGroup(3, [tag], name=name)
    # finer elements in the joint zone (the carriage and the rail under it)
    field = gmsh.model.mesh.field
    box = field.add("Box")
    field.setNumber(box, "VIn", SIZE_JOINT_M)
    field.setNumber(box, "VOut", SIZE_M)
    for key, v in (("XMin", -0.04), ("XMax", 0.04), ("YMin", 0.02), ("YMax", 0.09), ("ZMin", -0.06), ("ZMax", 0.06)):
        field.setNumber(box, key, v)
    field.setAsBackgroundMesh(box)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay: deterministic
    gmsh.option.setNumber("Mesh.RandomSeed", 1)
    gmsh.model.mesh.generate(3)
    gmsh.model.mesh.setOrder(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
    gmsh.option.setNumber("Mesh.SaveAll", 0)
    gmsh.write(str(path))
    gmsh.finalize()
    return path


if __name__ == "__main__":
    print(f"wrote {build()}")
