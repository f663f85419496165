"""Read a user's solid mesh (anything meshio reads) with named groups: bodies and surfaces.

Named groups come from the file:

* gmsh ``.msh``: physical groups (``$PhysicalNames``; volume groups name bodies, surface groups
  name surfaces);
* Abaqus ``.inp``: element sets (``*ELSET``) of solid elements (bodies) and of face elements
  (surfaces);
* ``.vtu`` and other formats with cell data: one integer cell-data array per group, non-zero on the
  cells of that group (the layout :func:`jointid.fe.meshexport.write_mesh` writes).

Solid cells: quadratic tetrahedra (10 nodes) or hexahedra (20 or 27 nodes), solved with the
quadratic Lagrange elements of scikit-fem on the cells' corner nodes (straight-edged: a curved
mid-edge node is straightened, with a warning); linear cells only with ``allow_linear: true``
(they lock in bending).  One solid cell kind per mesh.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointid.errors import ModelError, NumericalWarning

SOLID = {"tetra": ("tet", 1), "tetra10": ("tet", 2), "hexahedron": ("hex", 1),
         "hexahedron20": ("hex", 2), "hexahedron27": ("hex", 2)}
"""meshio solid cell type -> (shape, order)."""
FACE = {"triangle": 3, "triangle6": 3, "quad": 4, "quad8": 4, "quad9": 4}
"""meshio face cell type -> number of corner nodes."""
# VTK/meshio edge list of the quadratic cells, in the order of their mid-edge nodes
_EDGES = {"tet": [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)],
          "hex": [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
                  (0, 4), (1, 5), (2, 6), (3, 7)]}
_N_CORNERS = {"tet": 4, "hex": 8}


@dataclass
class MeshFile:
    """A solid mesh read from a file, with its named groups.

    Attributes
    ----------
    mesh : skfem.MeshTet1 or skfem.MeshHex1
        The corner-node mesh (the quadratic element adds its own mid-edge DOFs).
    element : str
        ``tet2``, ``hex2`` (quadratic) or ``tet1``, ``hex1`` (linear).
    cell_groups : dict
        Group name -> solid cell indices (of ``mesh``).
    surfaces : dict
        Group name -> facet indices of ``mesh`` (boundary facets of the solid cells).
    path : str
    """

    mesh: object
    element: str
    cell_groups: dict[str, np.ndarray]
    surfaces: dict[str, np.ndarray]
    path: str

    def group_names(self) -> str:
        return (f"bodies (solid groups) {sorted(self.cell_groups) or 'none'}, "
                f"surfaces (face groups) {sorted(self.surfaces) or 'none'}")


def read_mesh(path: str | Path, *, allow_linear: bool = False) -> MeshFile:
    """Read ``path`` (any format meshio reads) into a :class:`MeshFile`.

    Raises
    ------
    ModelError
        The file is missing or unreadable, has no or mixed solid cells, linear cells without
        ``allow_linear``, or face groups whose faces are not faces of any solid cell.
    """
    import meshio

    path = str(path)
    if not Path(path).is_file():
        raise ModelError(f"{path}: no such mesh file — set model.path to a mesh file meshio can read "
                         "(gmsh .msh, Abaqus .inp, .vtu ...)")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = meshio.read(path)
    except Exception as exc:  # meshio raises many kinds (ReadError, KeyError, ValueError ...)
        raise ModelError(f"{path}: meshio cannot read this file ({type(exc).__name__}: {exc}) — export it "
                         "as gmsh .msh (format 2.2 or 4.1), Abaqus .inp or .vtu") from None
    kinds = [b.type for b in m.cells if b.type in SOLID]
    if not kinds:
        raise ModelError(f"{path}: no solid cells (found {sorted({b.type for b in m.cells})}) — jointid needs a "
                         "volume mesh of tetrahedra or hexahedra, not only a surface mesh")
    shapes = {SOLID[k] for k in kinds}
    if len(shapes) > 1:
        raise ModelError(f"{path}: mixed solid cells {sorted(set(kinds))} — use one kind for the whole mesh "
                         "(all quadratic tetrahedra, or all quadratic hexahedra)")
    shape, order = shapes.pop()
    if order == 1 and not allow_linear:
        raise ModelError(f"{path}: linear {kinds[0]} cells lock in bending and give frequencies that are too "
                         "high — mesh with quadratic cells (gmsh: Mesh.ElementOrder = 2; tetra10 or "
                         "hexahedron20/27), or set model.allow_linear: true to use them anyway")
    if order == 1:
        warnings.warn(f"{path}: linear {kinds[0]} cells: bending is too stiff (locking) — check the "
                      "frequencies against a quadratic mesh", NumericalWarning, stacklevel=2)
    groups = _named_groups(m)
    solid_blocks = [i for i, b in enumerate(m.cells) if b.type in SOLID]
    offsets = np.cumsum([0] + [len(m.cells[i].data) for i in solid_blocks])
    conn = np.vstack([m.cells[i].data for i in solid_blocks])
    mesh, corners = _corner_mesh(m.points, conn, shape, path)
    if order == 2:
        _check_straight(m.points, conn, shape, path)
    cell_groups, face_cells = {}, {}
    for name, per_block in groups.items():
        cells = [offsets[solid_blocks.index(i)] + np.asarray(idx, np.int64)
                 for i, idx in per_block.items() if i in solid_blocks and len(idx)]
        faces = [m.cells[i].data[np.asarray(idx, np.int64)][:, : FACE[m.cells[i].type]]
                 for i, idx in per_block.items() if m.cells[i].type in FACE and len(idx)]
        if cells:
            cell_groups[name] = np.concatenate(cells)
        if faces:
            face_cells.setdefault(name, []).extend(faces)
    surfaces = {}
    for name, blocks in face_cells.items():
        surfaces[name] = _facets_of(mesh, corners, blocks, name, path)
    return MeshFile(mesh=mesh, element=f"{shape}{order}", cell_groups=cell_groups, surfaces=surfaces, path=path)


def _named_groups(m) -> dict[str, dict[int, np.ndarray]]:
    """Group name -> {cell block index: cell indices in that block}, from every naming scheme."""
    out: dict[str, dict[int, np.ndarray]] = {}
    for name, per_block in (m.cell_sets or {}).items():
        if name.startswith("gmsh:"):
            continue
        out[name] = {i: np.asarray(idx) for i, idx in enumerate(per_block) if idx is not None and len(idx)}
    phys = m.cell_data.get("gmsh:physical")
    if phys is not None and m.field_data:
        for name, (tag, *_dim) in m.field_data.items():
            hit = {i: np.flatnonzero(np.asarray(a) == tag) for i, a in enumerate(phys)}
            hit = {i: idx for i, idx in hit.items() if len(idx)}
            if hit:
                out.setdefault(name, {}).update(hit)
    for key, arrays in m.cell_data.items():
        if key.startswith("gmsh:") or key in out:
            continue
        arrays = [np.asarray(a) for a in arrays]
        if not all(a.ndim == 1 and np.issubdtype(a.dtype, np.integer) for a in arrays):
            continue
        hit = {i: np.flatnonzero(a != 0) for i, a in enumerate(arrays)}
        hit = {i: idx for i, idx in hit.items() if len(idx)}
        if hit:
            out[key] = hit
    return out


def _corner_mesh(points: np.ndarray, conn: np.ndarray, shape: str, path: str):
    """scikit-fem mesh on the corner nodes of the solid cells; returns ``(mesh, corner index of
    every file node or -1)``."""
    from skfem import MeshHex1, MeshTet1
    from skfem.io.meshio import INV_HEX_MAPPING

    nc = _N_CORNERS[shape]
    t = conn[:, :nc]
    used = np.unique(t)
    corner = -np.ones(len(points), np.int64)
    corner[used] = np.arange(len(used))
    p = np.ascontiguousarray(points[used, :3].T, dtype=float)
    t = corner[t].T
    if shape == "hex":
        t = t[INV_HEX_MAPPING[:8]]
    cls = MeshHex1 if shape == "hex" else MeshTet1
    try:
        mesh = cls(p, np.ascontiguousarray(t))
    except Exception as exc:
        raise ModelError(f"{path}: scikit-fem rejects the solid cells ({exc}) — check the mesh for "
                         "degenerate or inverted cells") from None
    return mesh, corner


def _check_straight(points: np.ndarray, conn: np.ndarray, shape: str, path: str) -> None:
    """Warn when mid-edge nodes are off the straight edges (the solve straightens them)."""
    edges = np.array(_EDGES[shape])
    nc = _N_CORNERS[shape]
    if conn.shape[1] < nc + len(edges):
        return
    a, b = points[conn[:, edges[:, 0]], :3], points[conn[:, edges[:, 1]], :3]
    mid = points[conn[:, nc: nc + len(edges)], :3]
    length = np.linalg.norm(b - a, axis=2)
    dev = np.linalg.norm(mid - 0.5 * (a + b), axis=2) / np.maximum(length, 1e-300)
    if dev.max() > 1e-6:
        warnings.warn(f"{path}: mid-edge nodes lie up to {dev.max():.1e} edge lengths off the straight "
                      "edges; the cells are solved straight-edged — refine curved surfaces so that "
                      "this stays small", NumericalWarning, stacklevel=3)


def _facets_of(mesh, corner: np.ndarray, blocks: list[np.ndarray], name: str, path: str) -> np.ndarray:
    """Facet indices of ``mesh`` matching the face cells (corner node ids of the file)."""
    n_corners = mesh.facets.shape[0]
    if any(b.shape[1] != n_corners for b in blocks):
        raise ModelError(f"{path}: surface {name!r} has faces with {sorted({b.shape[1] for b in blocks})} corners "
                         f"but the solid cells have {n_corners}-corner faces — name faces of the solid cells")
    faces = corner[np.vstack(blocks)]
    if (faces < 0).any():
        bad = int((faces < 0).any(axis=1).sum())
        raise ModelError(f"{path}: surface {name!r}: {bad} of {len(faces)} faces use nodes of no solid cell "
                         "— the surface is not on any body; put it on the faces of a body's cells")
    fkeys = np.sort(mesh.facets, axis=0).T
    keys = np.sort(faces, axis=1)
    _, inverse = np.unique(np.vstack([fkeys, keys]), axis=0, return_inverse=True)
    inverse = inverse.ravel()
    facet_of_key = np.full(inverse.max() + 1, -1, np.int64)
    facet_of_key[inverse[: len(fkeys)]] = np.arange(len(fkeys))
    hit = facet_of_key[inverse[len(fkeys):]]
    if (hit < 0).any():
        raise ModelError(f"{path}: surface {name!r}: {int((hit < 0).sum())} of {len(hit)} faces are not faces of "
                         "the solid cells — the surface is not on any body; mesh it together with its volume")
    return np.unique(hit)
