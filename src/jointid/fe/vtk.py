"""ParaView export (VTK XML unstructured grid via meshio): mesh with part ids and mode shapes."""

from __future__ import annotations

import re

import numpy as np
import scipy.sparse as sp
from skfem import MeshHex, MeshTet
from skfem.io.meshio import to_meshio

from jointid.fe.fem import Model
from jointid.io import atomic_path


def write_mesh_vtu(model: Model, path, modes: np.ndarray | None = None, freqs_Hz=None, *,
                   descriptions=None) -> None:
    """Write the linear (8-node) skeleton of the mesh; mode shapes at the vertices as point data.

    ``modes`` is ``(n_dofs, n_modes)``; each becomes a vector field ``mode_<i>_<f>Hz[_<description>]``
    (open in ParaView, Warp By Vector).  The frequencies are also field data ``freq_Hz`` (one value
    per mode, in order), and the cells carry their part id (``part``).
    """
    mesh_arrays = model.meta["mesh"]
    t = np.asarray(mesh_arrays["t"], np.int64)
    mesh = (MeshTet if t.shape[0] == 4 else MeshHex)(np.asarray(mesh_arrays["p"], float), t)
    point_data = {}
    field_data = {}
    if modes is not None:
        nv = mesh.p.shape[1]  # vertex dofs come first in scikit-fem's numbering
        to_vertices = None
        if "vertex_indptr" in mesh_arrays:  # hanging nodes: vertices from the free nodes
            to_vertices = sp.csr_matrix((mesh_arrays["vertex_data"], mesh_arrays["vertex_indices"],
                                         mesh_arrays["vertex_indptr"]), shape=(nv, modes.shape[0] // 3))
        for j in range(modes.shape[1]):
            if to_vertices is None:
                u = modes[: 3 * nv, j].reshape(nv, 3)
            else:
                u = to_vertices @ modes[:, j].reshape(-1, 3)
            tag = f"mode_{j + 1:02d}" + (f"_{freqs_Hz[j]:.0f}Hz" if freqs_Hz is not None else "")
            if descriptions is not None:
                tag += "_" + re.sub(r"[^A-Za-z0-9]+", "_", str(descriptions[j])).strip("_")
            point_data[tag] = u
        if freqs_Hz is not None:
            field_data["freq_Hz"] = np.asarray(freqs_Hz, float)
    m = to_meshio(mesh, point_data=point_data, cell_data={"part": [np.asarray(mesh_arrays["part"])]})
    with atomic_path(path) as tmp:
        m.write(str(tmp), file_format="vtu")
        if field_data:  # meshio 5 does not write field data: VTK XML holds it before the piece
            text = tmp.read_text()
            block = "".join(f'<DataArray type="Float64" Name="{name}" NumberOfTuples="{len(v)}" format="ascii">\n'
                            + " ".join(repr(float(x)) for x in v) + "\n</DataArray>\n"
                            for name, v in field_data.items())
            head = f"<UnstructuredGrid>\n<FieldData>\n{block}</FieldData>\n"
            tmp.write_text(text.replace("<UnstructuredGrid>\n", head, 1))
