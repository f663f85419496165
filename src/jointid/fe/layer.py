"""Zero-thickness spring layers between two surfaces whose meshes need not match, and the
interpolation of a field at points projected onto a surface.

A layer joins side A (the surface it is integrated over) to side B (node-to-surface): at each
quadrature point ``x`` of A's faces the partner point is the closest point ``pi(x)`` on B's faces,
and the gap vector is ``g = u_A(x) - u_B(pi(x))``.  One unit layer term per component ``e`` (a unit
vector field):

    K_e = int_A (e . (N_A - N_B))^T (e . (N_A - N_B)) dA       (1 N/m^3 per unit area)

so ``k'' K_e`` is the layer of stiffness ``k''`` [N/m^3] in that component, and every term is
positive semi-definite: the affine form ``K(theta) = K0 + sum theta_i K_i`` is kept.  Components:

* ``normal``: the outward normal of A's face, ``n``;
* ``feed``: the joint's ``feed_axis`` projected onto the face plane, ``t1``;
* ``lateral``: ``n x t1``;
* ``tangential``: both tangential directions at once (``I - n n^T``, no axis needed);
* ``x``, ``y``, ``z``: a global axis; ``all``: all three (``I``).

On matching meshes the partner point is the coincident node and the terms equal the node-paired
layers of :func:`jointid.fe.fem.spring_layer` to round-off.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

COMPONENTS = ("normal", "feed", "lateral", "tangential", "x", "y", "z", "all")
_AXES = {"x": 0, "y": 1, "z": 2}


def closest_on_facets(mesh, facets: np.ndarray, x: np.ndarray, n_candidates: int = 16):
    """Closest point on the union of ``facets`` (triangles or planar quads) to each point.

    ``x``: (3, n).  Returns ``(y (3, n), facet (n,), distance (n,))``.  Candidates are the
    ``n_candidates`` facets with the nearest centroids (quads split into two triangles).
    """
    corners = mesh.p[:, mesh.facets[:, facets]]  # (3, nc, nf)
    tris = [(0, 1, 2)] if corners.shape[1] == 3 else [(0, 1, 2), (0, 2, 3)]
    centroid = corners.mean(axis=1).T
    k = min(n_candidates, len(facets))
    _, cand = cKDTree(centroid).query(x.T, k=k)
    cand = cand.reshape(x.shape[1], k)
    best = np.full(x.shape[1], np.inf)
    y = np.zeros_like(x, dtype=float)
    which = np.zeros(x.shape[1], np.int64)
    for j in range(k):
        f = cand[:, j]
        for a, b, c in tris:
            q = _closest_on_triangle(x.T, corners[:, a, f].T, corners[:, b, f].T, corners[:, c, f].T)
            d = np.linalg.norm(q - x.T, axis=1)
            better = d < best
            best[better], y[:, better], which[better] = d[better], q[better].T, f[better]
    return y, facets[which], best


def _closest_on_triangle(p, a, b, c):
    """Closest points on triangles ``abc`` to points ``p`` (all (n, 3)); Ericson, Real-Time
    Collision Detection, 5.1.5, vectorised."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    denom = va + vb + vc
    with np.errstate(divide="ignore", invalid="ignore"):
        v, w = vb / denom, vc / denom
        out = a + ab * v[:, None] + ac * w[:, None]  # inside the face
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    cases = [
        ((d1 <= 0) & (d2 <= 0), a),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * t_ab[:, None]),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * t_ac[:, None]),
        ((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), b + (c - b) * t_bc[:, None]),
    ]
    done = np.zeros(len(p), bool)
    for mask, val in cases:
        use = mask & ~done
        out[use] = val[use]
        done |= use
    return out


def interpolation_at(basis, cells: np.ndarray, y: np.ndarray) -> sp.csr_matrix:
    """Scalar interpolation matrix ``(n, N)`` of ``basis`` at points ``y`` (3, n) known to lie in
    (or on the boundary of) the elements ``cells``."""
    pts = basis.mapping.invF(y[:, :, None], tind=cells)
    phis = np.array([basis.elem.gbasis(basis.mapping, pts, k, tind=cells)[0] for k in range(basis.Nbfun)])
    phis = phis.reshape(basis.Nbfun, -1)
    rows = np.tile(np.arange(y.shape[1]), basis.Nbfun)
    cols = basis.element_dofs[:, cells].ravel()
    P = sp.csr_matrix((phis.ravel(), (rows, cols)), shape=(y.shape[1], basis.N))
    P.data[np.abs(P.data) < 1e-13] = 0.0
    P.eliminate_zeros()
    return P


def surface_interpolation(basis, facets: np.ndarray, x: np.ndarray):
    """Interpolation at the points ``x`` (3, n) projected onto ``facets``: ``(P (n, N) scalar,
    distance (n,) from each point to the surface, projected points (3, n))``."""
    y, facet, dist = closest_on_facets(basis.mesh, facets, x)
    cells = basis.mesh.f2t[0, facet]
    return interpolation_at(basis, cells, y), dist, y


def component_vectors(component: str, normals: np.ndarray, feed_axis=None) -> list[np.ndarray]:
    """Unit vector fields (3, nq) of a layer component at points with unit normals ``normals``
    (3, nq); ``tangential`` and ``all`` give two and three fields whose terms add up."""
    nq = normals.shape[1]
    if component in _AXES:
        e = np.zeros((3, nq))
        e[_AXES[component]] = 1.0
        return [e]
    if component == "all":
        return [np.repeat(np.eye(3)[:, [i]], nq, axis=1) for i in range(3)]
    if component == "normal":
        return [normals]
    if component in ("feed", "lateral"):
        if feed_axis is None:
            raise ValueError(f"component {component!r} needs the joint's feed_axis")
        a = np.asarray(feed_axis, float)[:, None]
        t1 = a - normals * np.einsum("iq,i->q", normals, a[:, 0])[None, :]
        norm = np.linalg.norm(t1, axis=0)
        if norm.min() < 1e-6 * np.linalg.norm(a):
            raise ValueError(f"feed_axis {list(a[:, 0])} is normal to the joint surface: it has no direction "
                             "in the face plane")
        t1 = t1 / norm
        return [t1] if component == "feed" else [np.cross(normals.T, t1.T).T]
    if component == "tangential":
        # I - n n^T = t1 t1^T + t2 t2^T with any orthonormal tangents
        helper = np.where(np.abs(normals[0:1]) < 0.9, np.array([[1.0], [0.0], [0.0]]), np.array([[0.0], [1.0], [0.0]]))
        t1 = helper - normals * np.einsum("iq,iq->q", normals, helper)[None, :]
        t1 /= np.linalg.norm(t1, axis=0)
        return [t1, np.cross(normals.T, t1.T).T]
    raise ValueError(f"unknown layer component {component!r} (choose from {COMPONENTS})")


def spring_layer_terms(basis, facets_a: np.ndarray, facets_b: np.ndarray, components, *, intorder: int,
                       feed_axis=None, max_gap_m: float = np.inf):
    """Unit spring-layer terms between surface A (``facets_a``, integrated over) and surface B.

    Returns ``(terms, info)``: ``terms`` maps each component to a vector ``(3N, 3N)`` CSR matrix,
    ``info`` holds ``area_m2`` (of A) and ``max_gap_m`` (largest distance from a quadrature point of A
    to B).  Raises ``ValueError`` when the gap exceeds ``max_gap_m``.
    """
    from skfem import FacetBasis

    fb = FacetBasis(basis.mesh, basis.elem, facets=facets_a, intorder=intorder)
    xq = np.asarray(fb.global_coordinates())  # (3, nf, nqp)
    nf, nqp = xq.shape[1:]
    x = xq.reshape(3, -1)
    w = np.asarray(fb.dx).ravel()
    normals = np.asarray(fb.normals).reshape(3, -1)
    vals = np.stack([np.asarray(fb.basis[i][0]) for i in range(fb.Nbfun)])  # (nloc, nf, nqp)
    rows = np.broadcast_to(np.arange(nf * nqp).reshape(1, nf, nqp), vals.shape).ravel()
    cols = np.broadcast_to(fb.element_dofs[:, :, None], vals.shape).ravel()
    NA = sp.csr_matrix((vals.ravel(), (rows, cols)), shape=(nf * nqp, basis.N))
    NB, dist, _ = surface_interpolation(basis, facets_b, x)
    gap = float(dist.max(initial=0.0))
    if gap > max_gap_m:
        raise ValueError(f"the surfaces are up to {gap:.3g} m apart (tolerance {max_gap_m:.3g} m)")
    J = (NA - NB).tocoo()
    W = sp.diags(w)
    terms = {}
    for comp in components:
        total = None
        for e in component_vectors(comp, normals, feed_axis):
            G = sp.csr_matrix((np.concatenate([J.data * e[c, J.row] for c in range(3)]),
                               (np.tile(J.row, 3), np.concatenate([3 * J.col + c for c in range(3)]))),
                              shape=(J.shape[0], 3 * basis.N))
            K = (G.T @ W @ G).tocsr()
            total = K if total is None else total + K
        total.data[np.abs(total.data) < 1e-14 * np.abs(total.data).max(initial=1.0)] = 0.0
        total.eliminate_zeros()
        terms[comp] = total
    return terms, {"area_m2": float(w.sum()), "max_gap_m": gap}
