"""Hammer-tip patch: load and response vectors averaged over a small disc of a top surface.

A point load on a 3-D solid has an unbounded local flexibility (the displacement under it grows
without limit as the mesh is refined), so a drive-point FRF taken at one interpolation point depends
on the mesh.  An impact hammer loads a patch of a few millimetres; here the unit force is spread
uniformly over a disc of diameter ``d`` in the surface plane (normal Y) and the response is the
average displacement over the same disc (the work-conjugate of that load):

``p_i = (1 / A) * integral over the disc of N_i dA``

for each shape function ``N_i``, evaluated with a polar quadrature (Gauss-Legendre in the radius,
uniform in the angle) through the model's own basis (rebuilt from the cached mesh; a mesh with
hanging nodes is mapped onto its free nodes like the model).  For ``d -> 0`` the row is the model's
``probe`` row; once the mesh resolves the disc, the flexibility converges.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from jointid.errors import ConfigError, ModelError
from jointid.fe import fem

__all__ = ["N_RADIAL", "N_ANGULAR", "disc_points", "patch_probe"]

N_RADIAL = 6
"""Gauss-Legendre points in the radius of the disc quadrature."""
N_ANGULAR = 24
"""Equally spaced angles of the disc quadrature."""
_NUDGE_M = 1e-7  # onto the solid side of the top surface, as the model's probe


def disc_points(centre_xz, diameter_m: float, n_radial: int = N_RADIAL, n_angular: int = N_ANGULAR):
    """Quadrature of a disc in the X-Z plane: points ``(2, n)`` (x, z in m) and weights ``(n,)``
    summing to 1 (the mean over the disc).  Exact for polynomials of degree ``2 n_radial - 2`` in the
    radius times trigonometric polynomials of order ``< n_angular``."""
    a = 0.5 * float(diameter_m)
    t, wt = np.polynomial.legendre.leggauss(int(n_radial))
    r = 0.5 * a * (t + 1.0)  # (0, a)
    wr = 0.5 * a * wt * r  # integral of r dr
    th = 2 * np.pi * (np.arange(int(n_angular)) + 0.5) / int(n_angular)
    R, TH = np.meshgrid(r, th, indexing="ij")
    W = np.repeat(wr[:, None], th.size, axis=1) * (2 * np.pi / th.size)
    x = float(centre_xz[0]) + (R * np.cos(TH)).ravel()
    z = float(centre_xz[1]) + (R * np.sin(TH)).ravel()
    w = W.ravel()
    return np.vstack([x, z]), w / w.sum()


def _basis(model):
    """The model's scalar basis rebuilt from its cached mesh, and the map ``T`` from its free nodes
    (None without hanging nodes)."""
    from skfem import Basis, MeshHex, MeshTet

    from jointid.geometry import localrefine
    from jointid.geometry.rig import body_of

    m = model.meta.get("mesh") or {}
    if "p" not in m or "t" not in m:
        raise ModelError("patch_probe: the model has no mesh (meta['mesh']); rebuild it with the mesh rule")
    t = np.asarray(m["t"], np.int64)
    mesh = (MeshTet if t.shape[0] == 4 else MeshHex)(np.asarray(m["p"], float), t)
    element = model.meta.get("element", "hex2")
    basis = Basis(mesh, fem.ELEMENTS[element][0](), intorder=1)  # only probes are evaluated
    T = None
    if "vertex_indptr" in m:  # hanging nodes: the model lives on the free nodes
        xyz = mesh.p[:, mesh.t]  # (3, 8, n_cells)
        body = body_of(np.asarray(m["part"]))
        T, _ = localrefine.hanging_constraints(basis.doflocs, basis.element_dofs, xyz.min(axis=1).T,
                                               xyz.max(axis=1).T, body, localrefine.ORDER[element])
    return basis, T


def _vector_rows(P: sp.spmatrix, T) -> sp.csr_matrix:
    """Scalar probe rows ``(n_pts, N)`` -> vector rows ``(3 n_pts, 3 N')`` ordered (point, direction)
    as ``model.probe``; ``T`` maps onto the free nodes."""
    if T is not None:
        P = sp.csr_matrix(P) @ T
    return fem.vector_rows(P)


def patch_probe(model, points: list[str], diameter_m: float, *, n_radial: int = N_RADIAL,
                n_angular: int = N_ANGULAR, check: bool = True) -> sp.csr_matrix:
    """Rows of the disc-averaged displacement (and of the uniform unit load) at measuring points.

    Parameters
    ----------
    model : jointid.fe.fem.Model
        Cached model with its mesh (``meta['mesh']``) and measuring points (``meta['points']``).
    points : list of str
        Measuring-point names (on a top surface, normal Y), e.g. ``["T01", ..., "T18"]``.
    diameter_m : float
        Disc diameter (m); 0 gives the model's point ``probe`` rows.
    n_radial, n_angular : int
        Disc quadrature (:func:`disc_points`).
    check : bool
        Check that the rebuilt basis reproduces the model's probe rows at the disc centres (the DOF
        numbering is the model's); a mismatch raises :class:`ModelError`.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (3 * len(points), n_dofs)
        Rows ordered (point, direction x, y, z), like ``model.probe``; each row sums to 1.
    """
    import pandas as pd

    from jointid.geometry.points import dof_labels

    table = pd.DataFrame(model.meta["points"])
    labels = dof_labels(table)
    unknown = [p for p in points if f"{p}:y" not in labels]
    if unknown:
        raise ConfigError(f"patch_probe: {unknown} are not measuring points of the model")
    rows = np.concatenate([[labels.index(f"{p}:{d}") for d in "xyz"] for p in points])
    if not diameter_m > 0:
        return model.probe[rows].tocsr()
    basis, T = _basis(model)
    pts = table.set_index("point").loc[list(points)]
    xz, w = disc_points([0.0, 0.0], diameter_m, n_radial, n_angular)
    if model.meta.get("kind") == "mesh":  # as the model's probe: projected onto the nearest surface
        from jointid.fe.layer import surface_interpolation

        facets = basis.mesh.boundary_facets()
        nudge, probes = 0.0, lambda xyz: surface_interpolation(basis, facets, xyz)[0]
    else:
        nudge, probes = _NUDGE_M, basis.probes
    blocks = []
    for _, pt in pts.iterrows():
        xyz = np.vstack([pt.x_m + xz[0], np.full(w.size, pt.y_m - nudge), pt.z_m + xz[1]])
        P = sp.csr_matrix(probes(xyz))  # (n_q, N)
        blocks.append(sp.csr_matrix(w[None, :]) @ P)
    out = _vector_rows(sp.vstack(blocks), T)
    if check:
        centre = np.vstack([pts.x_m, pts.y_m - nudge, pts.z_m])
        ref = _vector_rows(sp.csr_matrix(probes(centre)), T)
        err = abs(ref - model.probe[rows]).max()
        if err > 1e-8:
            raise ModelError(f"patch_probe: the basis rebuilt from the cached mesh does not reproduce the "
                             f"model's probe rows (max difference {err:.1e}); rebuild the model (mesh rule)")
    return out.tocsr()
