"""Local refinement of the tensor grid at re-entrant edges, made conforming by hanging-node constraints.

Where solids meet at a 90° re-entrant edge (a rail foot on the base, a block under the table, the
block's inner corner over the rail) the stresses are singular and the frequencies of the modes that
load those edges converge only about linearly in the size of the cells touching them.  A tensor grid
can shrink those cells only by adding grid lines that run through the whole rig; here the cells that
touch such an edge are split into eight instead, ``levels`` times over (each time the children that
still touch the edge), and nothing else changes.

The split cells leave *hanging* nodes: nodes of the small cells on a face or edge of a larger
neighbour.  Every hanging node is tied to the larger cell's (triquadratic or trilinear) interpolant at
its position, and nodes that sit at the same place in one body are merged, so the finite-element space
stays conforming (continuous) and a refined mesh contains the coarse one.  The constraints are a sparse
map ``u_all = T u_free`` from the free nodes to every node of the scikit-fem mesh; the model is
assembled on the whole mesh and projected, ``K_free = T^T K T``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree
from skfem import MeshHex

_TOL = 1e-9
ORDER = {"hex1": 1, "hex2": 2}  # polynomial order of the mesh.element choices (nodal Lagrange)
# scikit-fem's vertex order of a hexahedron (MeshHex's reference cell)
_CORNERS = np.array([[0, 0, 0], [0, 0, 1], [0, 1, 0], [1, 0, 0], [0, 1, 1], [1, 0, 1], [1, 1, 0], [1, 1, 1]])


def reentrant_segments(lines: tuple[np.ndarray, np.ndarray, np.ndarray], group: np.ndarray) -> list[np.ndarray]:
    """Re-entrant edges of a tensor grid of cells.

    ``lines`` are the grid coordinates per axis, ``group`` the ``(nx, ny, nz)`` bonded group of its
    cells (-1 void; cells of one group are joined rigidly or by a stiff layer, different groups only
    by joint springs).  An edge of the grid is re-entrant when exactly three of the four cells around
    it belong to one group: the inner corner of an L-shaped solid.  Returns, per axis ``a``, an
    ``(n, 4)`` array of segments along ``a``: the two fixed coordinates (the other axes in increasing
    order), then the segment's start and end along ``a`` — consecutive edges on one line merged.
    """
    out = []
    for a in range(3):
        b, c = [ax for ax in range(3) if ax != a]
        g = np.pad(np.moveaxis(group, (b, c, a), (0, 1, 2)), ((1, 1), (1, 1), (0, 0)), constant_values=-1)
        re = np.zeros((g.shape[0] - 1, g.shape[1] - 1, g.shape[2]), bool)  # around each edge
        for k in np.unique(group[group >= 0]):
            s = (g == k).astype(np.int8)
            re |= (s[:-1, :-1] + s[1:, :-1] + s[:-1, 1:] + s[1:, 1:]) == 3
        segs = []
        for i, j in zip(*np.nonzero(re.any(axis=2))):
            on = np.concatenate([[False], re[i, j], [False]])
            starts = np.flatnonzero(on[1:] & ~on[:-1])
            ends = np.flatnonzero(~on[1:] & on[:-1])
            for k0, k1 in zip(starts, ends):
                segs.append([lines[b][i], lines[c][j], lines[a][k0], lines[a][k1]])
        out.append(np.array(segs, float).reshape(-1, 4))
    return out


def clip_segments(segments: list[np.ndarray], lo: np.ndarray, hi: np.ndarray) -> list[np.ndarray]:
    """The parts of the segments inside the box ``[lo, hi]``."""
    out = []
    for a, segs in enumerate(segments):
        b, c = [ax for ax in range(3) if ax != a]
        s = segs.copy()
        s[:, 2] = np.maximum(s[:, 2], lo[a])
        s[:, 3] = np.minimum(s[:, 3], hi[a])
        inside = ((s[:, 0] >= lo[b] - _TOL) & (s[:, 0] <= hi[b] + _TOL) & (s[:, 1] >= lo[c] - _TOL)
                  & (s[:, 1] <= hi[c] + _TOL) & (s[:, 3] - s[:, 2] > _TOL))
        out.append(s[inside])
    return out


def touching(lo: np.ndarray, hi: np.ndarray, segments: list[np.ndarray]) -> np.ndarray:
    """``(n, 3)`` mask: box ``[lo, hi]`` has a part of positive length of a segment along axis ``a``
    (see :func:`reentrant_segments`) on one of its edges."""
    hit = np.zeros((len(lo), 3), bool)
    for a, segs in enumerate(segments):
        b, c = [ax for ax in range(3) if ax != a]
        for pb, pc, s0, s1 in segs:
            on_b = (np.abs(lo[:, b] - pb) < _TOL) | (np.abs(hi[:, b] - pb) < _TOL)
            on_c = (np.abs(lo[:, c] - pc) < _TOL) | (np.abs(hi[:, c] - pc) < _TOL)
            overlap = np.minimum(hi[:, a], s1) - np.maximum(lo[:, a], s0) > _TOL
            hit[:, a] |= on_b & on_c & overlap
    return hit


def refine_at(lo: np.ndarray, hi: np.ndarray, segments: list[np.ndarray], level: np.ndarray, *attrs: np.ndarray):
    """One level of refinement at the segments: the boxes of the deepest ``level`` that touch a
    segment are halved across it (a box at an edge along Z is cut in X and Y only, since the field
    near an edge varies fast only across it); their halves get the next level.  ``attrs`` (per-box
    arrays) are inherited.  Returns ``(lo, hi, level, *attrs)``."""
    lev = level.max() if len(level) else 0
    hit = touching(lo, hi, segments) & (level == lev)[:, None]
    cut = np.stack([hit[:, [1, 2]].any(axis=1), hit[:, [0, 2]].any(axis=1), hit[:, [0, 1]].any(axis=1)], axis=1)
    level = np.where(cut.any(axis=1), lev + 1, level)
    for axis in range(3):
        lo, hi, cut, level, *attrs = bisect(lo, hi, cut[:, axis], axis, cut, level, *attrs)
    return (lo, hi, level, *attrs)


def bisect(lo: np.ndarray, hi: np.ndarray, mask: np.ndarray, axis: int, *attrs: np.ndarray):
    """Cut the boxes selected by ``mask`` in two halves across ``axis``; ``attrs`` (per-box arrays) are
    inherited.  Returns ``(lo, hi, *attrs)``, the halves appended after the boxes left whole."""
    keep = ~mask
    mid = 0.5 * (lo[mask, axis] + hi[mask, axis])
    lo1, hi0 = lo[mask].copy(), hi[mask].copy()
    hi0[:, axis] = mid
    lo1[:, axis] = mid
    new_attrs = [np.concatenate([x[keep], x[mask], x[mask]]) for x in attrs]
    return (np.concatenate([lo[keep], lo[mask], lo1]), np.concatenate([hi[keep], hi0, hi[mask]]), *new_attrs)


def split(lo: np.ndarray, hi: np.ndarray, mask: np.ndarray, *attrs: np.ndarray):
    """Split the boxes selected by ``mask`` into their eight octants (see :func:`bisect`)."""
    out = (lo, hi, mask, *attrs)
    for axis in range(3):
        lo, hi, mask, *attrs = out
        out = bisect(lo, hi, mask, axis, mask, *attrs)
    lo, hi, _, *attrs = out
    return (lo, hi, *attrs)


def box_mesh(lo: np.ndarray, hi: np.ndarray, body: np.ndarray) -> MeshHex:
    """Hexahedral mesh of axis-aligned boxes; corners are shared within a body and duplicated between
    bodies.  Boxes may meet non-conformingly (hanging nodes, see :func:`hanging_constraints`)."""
    corners = lo[:, None, :] + _CORNERS[None, :, :] * (hi - lo)[:, None, :]  # (n, 8, 3)
    scale = max(float(np.ptp(np.vstack([lo, hi]), axis=0).max()), 1.0)
    key = np.concatenate([np.repeat(body, 8)[:, None],
                          np.round(corners.reshape(-1, 3) / (scale * _TOL)).astype(np.int64)], axis=1)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    first = np.zeros(len(uniq), np.int64)
    first[inv[::-1]] = np.arange(len(inv))[::-1]
    p = corners.reshape(-1, 3)[first].T
    return MeshHex(np.ascontiguousarray(p), inv.reshape(-1, 8).T.copy())


def _lagrange_1d(x: np.ndarray, order: int) -> np.ndarray:
    """1D Lagrange basis on [0, 1] with equispaced nodes, ``(len(x), order + 1)``."""
    if order == 1:
        return np.stack([1 - x, x], axis=1)
    return np.stack([2 * (x - 0.5) * (x - 1), -4 * x * (x - 1), 2 * x * (x - 0.5)], axis=1)


def hanging_constraints(doflocs: np.ndarray, element_dofs: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                        body: np.ndarray, order: int) -> tuple[sp.csr_matrix, np.ndarray]:
    """Map ``T`` (``N x m``) from the free scalar DOFs to all ``N`` scalar DOFs of a box mesh.

    ``doflocs`` ``(3, N)`` and ``element_dofs`` ``(nloc, n_boxes)`` are the basis' (Lagrange element of
    ``order`` 1 or 2, nodal DOFs); ``lo``, ``hi`` the boxes, ``body`` the body of each.  DOFs at one
    place in one body are one node; a node lying on the boundary of a box without being one of its
    nodes is a hanging node and takes the box's interpolant there (the coarsest such box; chains of
    hanging nodes are resolved).  Returns ``(T, free)``: ``free[j]`` is a DOF standing for free node j.
    """
    n = doflocs.shape[1]
    dof_body = np.empty(n, np.int64)
    dof_body[element_dofs] = body[None, :]
    scale = max(float(np.ptp(doflocs, axis=1).max()), 1.0)
    key = np.concatenate([dof_body[:, None], np.round(doflocs.T / (scale * _TOL)).astype(np.int64)], axis=1)
    _, node = np.unique(key, axis=0, return_inverse=True)  # node of each DOF
    n_nodes = node.max() + 1
    rep = np.zeros(n_nodes, np.int64)
    rep[node[::-1]] = np.arange(n)[::-1]
    xyz = doflocs[:, rep].T
    # nodes of other bodies are kept apart by a shift far larger than the rig
    shifted = xyz + 10 * scale * dof_body[rep][:, None] * np.array([1.0, 0.0, 0.0])
    tree = cKDTree(shifted)
    half = 0.5 * (hi - lo)
    centre = 0.5 * (lo + hi) + 10 * scale * body[:, None] * np.array([1.0, 0.0, 0.0])
    candidates = tree.query_ball_point(centre, half.max(axis=1) * (1 + 1e-6) + scale * _TOL, p=np.inf)
    volume = np.prod(hi - lo, axis=1)
    owner = np.full(n_nodes, -1, np.int64)  # the coarsest box a node hangs on
    own_nodes = node[element_dofs]  # (nloc, n_boxes)
    for e, cand in enumerate(candidates):
        if len(cand) <= own_nodes.shape[0]:
            continue
        cand = np.asarray(cand)
        inside = np.all(np.abs(shifted[cand] - centre[e]) <= half[e] + scale * _TOL, axis=1)
        hang = np.setdiff1d(cand[inside], own_nodes[:, e])
        if len(hang):
            better = (owner[hang] < 0) | (volume[np.maximum(owner[hang], 0)] < volume[e])
            owner[hang[better]] = e
    hanging = np.flatnonzero(owner >= 0)
    free_nodes = np.flatnonzero(owner < 0)
    rows, cols, vals = [free_nodes], [free_nodes], [np.ones(len(free_nodes))]
    if len(hanging):
        e = owner[hanging]
        xi = (xyz[hanging] - lo[e]) / (hi[e] - lo[e])  # (nh, 3) local coordinates of the hanging nodes
        lat = np.rint(order * (doflocs[:, element_dofs[:, e]].transpose(1, 2, 0) - lo[e][None])
                      / (hi[e] - lo[e])[None]).astype(int)  # (nloc, nh, 3) lattice index of each box DOF
        w = np.ones(lat.shape[:2])
        for ax in range(3):
            L = _lagrange_1d(xi[:, ax], order)  # (nh, order + 1)
            w *= np.take_along_axis(L.T, lat[:, :, ax], axis=0)
        rows.append(np.repeat(hanging[None, :], lat.shape[0], axis=0).ravel())
        cols.append(node[element_dofs[:, e]].ravel())
        vals.append(w.ravel())
    C = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n_nodes, n_nodes))
    C.data[np.abs(C.data) < 1e-13] = 0.0
    C.eliminate_zeros()
    is_hanging = owner >= 0
    for _ in range(32):  # a master may itself hang on a still coarser box
        if not C[:, is_hanging].nnz:
            break
        C = (C @ C).tocsr()
        C.data[np.abs(C.data) < 1e-13] = 0.0
        C.eliminate_zeros()
    else:
        raise RuntimeError("hanging-node constraints do not resolve (cyclic dependency in the mesh)")
    Cf = C[:, free_nodes].tocsr()
    T = Cf[node].tocsr()
    return T, rep[free_nodes]


def boxes_at(lo: np.ndarray, hi: np.ndarray, pts: np.ndarray) -> list[np.ndarray]:
    """For each point ``(n, 3)``, the boxes whose closed box contains it."""
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    tol = _TOL * max(float(np.ptp(np.vstack([lo, hi]), axis=0).max()), 1.0)
    cand = cKDTree(centre).query_ball_point(pts, half.max() + tol, p=np.inf)
    out = []
    for x, c in zip(pts, cand):
        c = np.asarray(c, np.int64)
        out.append(c[np.all(np.abs(centre[c] - x) <= half[c] + tol, axis=1)] if len(c) else c)
    return out


def unmatched_across(mesh: MeshHex, body: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                     facets: np.ndarray) -> np.ndarray:
    """Boxes to split so that the cells on the two sides of the given interface facets match.

    ``facets`` are boundary facets of ``mesh`` (one box per element, ``lo``/``hi``) on a face where two
    bodies meet.  For each, the boxes of the other body just across it are found; along each axis in
    the plane of the facet, whichever of the facet and a box across is longer is marked for cutting
    across that axis.  Returns an ``(n_boxes, 3)`` boolean mask (box, axis).
    """
    mark = np.zeros((len(lo), 3), bool)
    if not len(facets):
        return mark
    owner = mesh.f2t[0, facets]
    fp = mesh.p[:, mesh.facets[:, facets]]  # (3, 4, nf)
    flo, fhi = fp.min(axis=1).T, fp.max(axis=1).T
    normal = np.argmin(fhi - flo, axis=1)
    rows = np.arange(len(facets))
    centre = 0.5 * (flo + fhi)
    sign = np.sign(centre[rows, normal] - 0.5 * (lo[owner] + hi[owner])[rows, normal])
    probe = centre.copy()
    probe[rows, normal] += 1e-7 * sign
    for f, found in enumerate(boxes_at(lo, hi, probe)):
        a = owner[f]
        for b in found[body[found] != body[a]]:
            for ax in range(3):
                if ax == normal[f]:
                    continue
                if lo[b, ax] < flo[f, ax] - _TOL or hi[b, ax] > fhi[f, ax] + _TOL:
                    mark[b, ax] = True
                if lo[b, ax] > flo[f, ax] + _TOL or hi[b, ax] < fhi[f, ax] - _TOL:
                    mark[a, ax] = True
    return mark
