"""Write the parametric rig as a mesh file with named groups, and the ``model:`` section that reads
it back (``model: {kind: mesh}``): the round trip that checks the mesh-in path against the rig, and
a starting point for a user who wants to edit the rig's mesh in another tool.

The file is gmsh 2.2 (``.msh``: 27-node hexahedra, 4-node faces, physical names) or, by extension,
``.vtu`` (one integer cell-data array per group).  Bodies are the rig's parts (``base``, ``rail``,
``carriage``, ``table``; carriages and table share nodes, so they are bonded); the joints are the
rig's contact faces (carriage side first) and the rails' fixing layer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from jointid.config.typed import ModelSpec
from jointid.geometry.rig import Box, PART_IDS

# rig term K_<face>_<d> -> component of that face's layer (top: normal y; flank: normal x; feed z)
_COMPONENT = {("top", "y"): "normal", ("top", "z"): "feed", ("top", "x"): "lateral",
              ("flank", "x"): "normal", ("flank", "z"): "feed", ("flank", "y"): "lateral"}


def _facets_in(mesh, owner_part: np.ndarray, part: int, boxes: list[Box]) -> np.ndarray:
    """Boundary facets of cells of ``part`` whose midpoints lie in one of the degenerate ``boxes``."""
    from jointid.geometry.mesh import _in_patch

    bnd = mesh.boundary_facets()
    mid = mesh.p[:, mesh.facets[:, bnd]].mean(axis=1).T
    return bnd[_in_patch(mid, boxes) & (owner_part[mesh.f2t[0, bnd]] == part)]


def rig_groups(spec: ModelSpec):
    """The corner mesh of the rig of ``spec``, the part of each cell and its named surfaces (facet indices)."""
    from jointid.geometry.mesh import mesh_from_config
    from jointid.geometry.rig import build_rig

    if spec.mesh.edge_refine_levels:
        from jointid.errors import ConfigError

        raise ConfigError("mesh.edge_refine_levels: the rig is exported without edge refinement (hanging "
                          "nodes) — set mesh.edge_refine_levels: 0")
    rig = build_rig(spec.rig.geometry)
    rm = mesh_from_config(rig, spec.mesh)
    mesh, part = rm.mesh, rm.part
    rail = PART_IDS["rail"]
    base = PART_IDS["base"]
    surfaces = {"carriage_top": rm.facets["top"], "carriage_flank": rm.facets["flank"],
                "rail_top": _facets_in(mesh, part, rail, rig.contact["top"]),
                "rail_flank": _facets_in(mesh, part, rail, rig.contact["flank"]),
                "rail_bottom": rm.facets["railfix"],
                "base_under_rail": _facets_in(mesh, part, base, rig.patches["railfix"]),
                "bottom": rm.facets["bottom"], "motor_patch": rm.facets["motor"],
                "table_top": rm.facets["table_top"], "table_edge": rm.facets["table_edge"]}
    if len(rm.facets["mount"]):
        surfaces["mount"] = rm.facets["mount"]
    return rig, mesh, part, surfaces


def model_section(spec: ModelSpec, mesh_path: str, points_path: str, areas: dict[str, float]) -> dict:
    """The ``model:`` section reading the exported rig back (same joint parameters as ``spec``);
    ``areas``: the surfaces' areas, m^2."""
    from jointid.fe.model import joint_terms, rail_fixing_N_per_m3

    laws: dict[str, dict] = {"top": {}, "flank": {}}
    for name, terms in joint_terms(spec.joints).items():
        for term in terms:
            _, face, d = term.split("_")
            laws[face][_COMPONENT[(face, d)]] = name
    rig = spec.rig
    joints = [{"name": face, "surfaces": [f"carriage_{face}", f"rail_{face}"], "feed_axis": [0.0, 0.0, 1.0],
               "law": law} for face, law in laws.items() if law]
    joints.append({"name": "railfix", "surfaces": ["rail_bottom", "base_under_rail"],
                   "law": {"all": rail_fixing_N_per_m3(rig)}})
    if rig.support_kind == "clamped":
        supports = [{"surface": "bottom", "kind": "clamped"}]
    else:
        supports = [{"surface": "mount", "kind": "foundation",
                     "k_N_per_m3": rig.k_mount_N_per_m / (areas["mount"] / 4)}]
    masses = [{"name": "motor", "surface": "motor_patch", "mass_kg": rig.motor_mass_kg},
              {"name": "table_top", "surface": "table_top", "mass_kg": 0.0},
              {"name": "table_edge", "surface": "table_edge", "mass_kg": 0.0}]
    bodies = {p: rig.part_materials[p] for p in ("base", "rail", "carriage", "table")}
    return {"kind": "mesh", "path": mesh_path, "bodies": bodies, "joints": joints, "supports": supports,
            "masses": masses, "points": points_path}


def write_mesh(path: str | Path, mesh, cell_groups: dict[str, np.ndarray], surfaces: dict[str, np.ndarray]) -> None:
    """Write a corner hexahedral mesh as quadratic hexahedra with named groups (``.msh``: gmsh 2.2
    with physical names, 27-node; ``.vtu``: one integer cell-data array per group, 27-node;
    ``.inp``: Abaqus element sets, 20-node)."""
    import meshio
    from skfem import Basis, ElementHex2
    from skfem.io.meshio import HEX_MAPPING

    basis = Basis(mesh, ElementHex2(), intorder=1)
    points = basis.doflocs.T
    hexes = basis.element_dofs[HEX_MAPPING].T
    names = list(cell_groups) + list(surfaces)
    faces = np.concatenate([np.asarray(surfaces[s]) for s in surfaces]) if surfaces else np.array([], int)
    quads = mesh.facets[:, faces].T  # corner nodes: the first vertices of the basis' dofs
    quads = _oriented_quads(mesh, quads)
    hex_tag = np.zeros(len(hexes), np.int64)
    for k, (name, cells) in enumerate(cell_groups.items()):
        hex_tag[cells] = k + 1
    face_tag = np.concatenate([np.full(len(surfaces[s]), len(cell_groups) + k + 1)
                               for k, s in enumerate(surfaces)]) if surfaces else np.array([], int)
    cells = [("hexahedron27", hexes), ("quad", quads)]
    path = str(path)
    if path.endswith(".inp"):  # Abaqus: element sets; meshio writes no 27-node brick, so C3D20
        offsets = np.cumsum([0] + [len(surfaces[s]) for s in surfaces])
        sets = {name: [np.asarray(c), np.array([], int)] for name, c in cell_groups.items()}
        sets.update({s: [np.array([], int), np.arange(offsets[k], offsets[k + 1])] for k, s in enumerate(surfaces)})
        meshio.write(path, meshio.Mesh(points, [("hexahedron20", hexes[:, :20]), ("quad", quads)], cell_sets=sets))
        return
    if path.endswith(".vtu"):
        data = {name: [(hex_tag == k + 1).astype(np.int32), (face_tag == k + 1).astype(np.int32)]
                for k, name in enumerate(names)}
        meshio.write(path, meshio.Mesh(points, cells, cell_data=data))
        return
    field = {name: np.array([k + 1, 3 if k < len(cell_groups) else 2]) for k, name in enumerate(names)}
    data = {"gmsh:physical": [hex_tag, face_tag], "gmsh:geometrical": [hex_tag, face_tag]}
    meshio.write(path, meshio.Mesh(points, cells, cell_data=data, field_data=field), file_format="gmsh22",
                 binary=False)


def _oriented_quads(mesh, quads: np.ndarray) -> np.ndarray:
    """Facet corners in cyclic order around the face (what mesh readers expect of a 4-node face)."""
    xyz = mesh.p[:, quads]  # (3, n, 4)
    c = xyz.mean(axis=2, keepdims=True)
    v = xyz - c
    ref = v[:, :, 0]
    normal = np.cross(v[:, :, 0].T, v[:, :, 1].T).T
    bad = np.linalg.norm(normal, axis=0) < 1e-14
    normal[:, bad] = np.cross(v[:, bad, 0].T, v[:, bad, 2].T).T
    angle = np.stack([np.arctan2(np.einsum("in,in->n", normal, np.cross(ref.T, v[:, :, k].T).T),
                                 np.einsum("in,in->n", ref, v[:, :, k])) for k in range(4)], axis=1)
    return np.take_along_axis(quads, np.argsort(angle, axis=1), axis=1)


def export_rig(spec: ModelSpec, mesh_path: str | Path, points_path: str | Path) -> dict:
    """Write the rig of ``spec`` as ``mesh_path`` and its measuring points as ``points_path``; return
    the ``model:`` section that reads them back."""
    from jointid.fe import fem
    from jointid.geometry.points import measuring_points
    from skfem import ElementHex2

    rig, mesh, part, surfaces = rig_groups(spec)
    groups = {name: np.flatnonzero(part == pid) for name, pid in PART_IDS.items() if pid >= 0}
    write_mesh(mesh_path, mesh, groups, surfaces)
    pts = measuring_points(spec.rig.geometry, rig.dims)
    pts.to_csv(points_path, index=False)
    areas = {s: float(fem.facet_mass(mesh, ElementHex2(), f, 4).sum()) for s, f in surfaces.items()}
    return model_section(spec, str(mesh_path), str(points_path), areas)


def main(argv: list[str] | None = None) -> int:
    """``jointid export-mesh``: write the configured rig as a mesh file with named groups, its
    measuring points and a config overlay that runs the workflow on the file."""
    import argparse

    import yaml

    from jointid.config import load_config
    from jointid.yamlio import read_merged

    ap = argparse.ArgumentParser(prog="jointid export-mesh", description=main.__doc__.split("\n\n")[0].replace("``", ""))
    ap.add_argument("--out", required=True, help="folder to write rig.<format>, points.csv and model.yaml into")
    ap.add_argument("--config", nargs="*", default=["config.yaml"], help="config files merged in order (default config.yaml)")
    ap.add_argument("--format", choices=("msh", "vtu", "inp"), default="msh",
                    help="gmsh 2.2 (default), VTK with one cell-data array per group, or Abaqus element sets")
    args = ap.parse_args(argv)
    spec = ModelSpec.from_config(load_config(read_merged(args.config)))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    section = export_rig(spec, out / f"rig.{args.format}", out / "points.csv")
    overlay = {"model": section, "mesh": {"extrapolate_edges": False}, "mesh_check": {"enabled": False}}
    (out / "model.yaml").write_text("# the rig read back from its mesh file: snakemake -j2 --configfile "
                                    f"{out / 'model.yaml'}\n" + yaml.safe_dump(overlay, sort_keys=False))
    print(f"export-mesh: wrote {section['path']}, {section['points']} and {out / 'model.yaml'}")
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(main())
