"""What the solvers of this layer need of a model: the protocol of an affine FE model.

``K(c) = K0 + sum c_a K_a`` and ``M(m) = M0 + sum m_b M_b``.  :class:`jointid.fe.fem.Model` is one;
the diagnosis's :class:`jointid.diagnosis.terms.System` (the model with its effect terms) is another.
The solvers (:class:`jointid.fe.reduced.ReducedSolver`, :class:`jointid.fe.pencil.FreePencil`,
:mod:`jointid.fe.warmstart`) are typed against this protocol, so that this layer names nothing above it.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import scipy.sparse as sp

__all__ = ["AffineModel", "sequential_sum"]


class AffineModel(Protocol):
    """An affine FE model.

    Attributes
    ----------
    stiffness, mass : dict of str -> sparse matrix
        The terms, ``K0`` and ``M0`` included (full size, ``n_dofs`` square).
    fixed : ndarray
        Clamped DOFs.
    probe : sparse matrix
        ``u_points = probe @ u``: the displacements at the measuring points.
    n_dofs : int
        Number of DOFs.
    """

    stiffness: dict[str, sp.spmatrix]
    mass: dict[str, sp.spmatrix]
    fixed: np.ndarray
    probe: sp.spmatrix

    @property
    def n_dofs(self) -> int: ...


def sequential_sum(base: sp.spmatrix, parts: list[tuple[float, sp.spmatrix]]) -> sp.csr_matrix:
    """``base + c1 A1 + c2 A2 + ...`` (``parts``: ``(c, A)`` pairs) added left to right, as ``out = out + c * A``
    adds them, to the bit: every entry gets the same additions in the same order, and an entry that sums to zero
    is dropped, as scipy drops it.  Only the rows the terms touch are summed (the joint layers, the foundation,
    a motor mass: a few per cent of the rows); the other rows of ``base`` are copied once, where the sum of whole
    matrices copies all of them at every term (on the thickness-halved default mesh, 18 terms: 1.4 s)."""
    base = sp.csr_matrix(base)
    if not parts:
        return base.copy()
    parts = [(c, sp.csr_matrix(A)) for c, A in parts]
    rows = np.unique(np.concatenate([np.flatnonzero(np.diff(A.indptr)) for _, A in parts]))
    sub = base[rows]
    for c, A in parts:
        sub = sub + c * A[rows]
    sub.sort_indices()
    n = base.shape[0]
    lengths = np.diff(base.indptr)
    lengths[rows] = np.diff(sub.indptr)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(lengths, out=indptr[1:])
    indices = np.empty(indptr[-1], dtype=base.indices.dtype)
    data = np.empty(indptr[-1], dtype=np.result_type(base.dtype, sub.dtype))
    kept = np.ones(n, bool)
    kept[rows] = False
    base_row = np.repeat(np.arange(n), np.diff(base.indptr))
    take = kept[base_row]
    dest = (indptr[:-1] - base.indptr[:-1])[base_row[take]] + np.flatnonzero(take)
    indices[dest], data[dest] = base.indices[take], base.data[take]
    sub_row = np.repeat(np.arange(len(rows)), np.diff(sub.indptr))
    dest = indptr[rows][sub_row] + (np.arange(sub.nnz) - sub.indptr[sub_row])
    indices[dest], data[dest] = sub.indices, sub.data
    out = sp.csr_matrix((data, indices, indptr.astype(base.indptr.dtype)), shape=base.shape)
    out.eliminate_zeros()  # the first sum drops explicit zeros of the untouched rows too
    return out
