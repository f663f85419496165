"""Assembly of the affine FE model ``K(theta) = K0 + sum_i theta_i K_i``, ``M(mu) = M0 + sum_j mu_j M_j``.

* ``K0``, ``M0``: isotropic linear elasticity and consistent mass of all solids (vectorised assembly of
  the nine scalar gradient blocks; identical to scikit-fem's ``linear_elasticity`` form, much faster).
* ``K_<face>_<dir>``: a zero-thickness spring layer on a joint face, unit stiffness per area (1 N/m^3):
  ``K = D^T S D``, ``S`` the facet mass matrix over the contact facets, ``D`` the jump
  ``u_carriage - u_rail`` in one global direction.  Multiplying by ``k''`` [N/m^3] gives the joint.
* ``K_mount``: base mounts, unit stiffness per area in all three directions against the ground.
* ``M_motor``: the motor primaries as a unit-mass (1 kg) layer spread over the table-underside patch.
* ``Model.solids``: the solids per part, ``K_solid_<part>`` and ``M_solid_<part>`` (``K0 = sum_b
  K_solid_b``), so that a part's Young's modulus and density are coefficients too
  (:mod:`jointid.fe.model`); :func:`assemble_elasticity` assembles one part with ``elements``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree
from skfem import BilinearForm, Basis, ElementHex1, ElementHex2, ElementTetP1, ElementTetP2, FacetBasis

from jointid.geometry.mesh import RigMesh

ELEMENTS = {"hex1": (ElementHex1, 2), "hex2": (ElementHex2, 4), "tet1": (ElementTetP1, 2),
            "tet2": (ElementTetP2, 4)}  # element, exact quadrature order of the mass
DIRS = {"x": 0, "y": 1, "z": 2}


@dataclass
class Model:
    """Assembled model matrices (vector DOFs interleaved: dof = 3 * scalar_dof + component).

    ``stiffness`` and ``mass`` map names to sparse CSR matrices: ``K0`` / ``M0`` plus affine terms.
    ``fixed`` lists constrained DOFs (clamped support), ``probe`` interpolates displacements at the
    measuring points: ``u_points = probe @ u`` with rows ordered (point, direction).
    """

    stiffness: dict[str, sp.csr_matrix]
    mass: dict[str, sp.csr_matrix]
    fixed: np.ndarray
    probe: sp.csr_matrix
    doflocs: np.ndarray  # (3, n_scalar_dofs)
    dof_part: np.ndarray  # (n_scalar_dofs,) part id owning each scalar dof (-1 if ambiguous)
    meta: dict = field(default_factory=dict)
    # fill-reducing ordering of K - sigma M on the free DOFs (PARDISO, 1-based), cached with the
    # model by the mesh stage so that no later factorisation has to reorder (None: not computed)
    ordering: np.ndarray | None = None
    # the solids per part (``K_solid_<part>``, ``M_solid_<part>``: elasticity and mass of one part at
    # its reference material, ``meta['solids']``), kept apart from ``stiffness``/``mass`` so that the
    # solvers iterating over the affine terms do not carry them; one part, ``meta['solids']
    # ['complement']`` (the largest), is not stored but formed when asked as K0 (M0) minus the others
    solids: dict = field(default_factory=dict)

    @property
    def n_dofs(self) -> int:
        return self.stiffness["K0"].shape[0]

    def K(self, coeffs: dict[str, float]) -> sp.csr_matrix:
        """``K0 + sum coeffs[name] * stiffness[name]``; a name ``K_solid_<part>`` takes the part's
        elasticity (:meth:`solid_term`), its coefficient ``E_part / E_part,ref - 1``."""
        return _affine_sum(self.stiffness, "K0", coeffs, self.solid_term)

    def M(self, coeffs: dict[str, float]) -> sp.csr_matrix:
        """``M0 + sum coeffs[name] * mass[name]``; a name ``M_solid_<part>`` takes the part's mass
        (:meth:`solid_term`), its coefficient ``rho_part / rho_part,ref - 1``."""
        return _affine_sum(self.mass, "M0", coeffs, self.solid_term)

    def solid_term(self, name: str) -> sp.csr_matrix:
        """The solid term ``K_solid_<part>`` or ``M_solid_<part>`` (see ``solids``): stored, or for the
        complement part ``K0 - sum of the stored parts`` (``M0 - ...``), formed on each call."""
        if name in self.solids:
            return self.solids[name]
        info = self.meta.get("solids") or {}
        group, _, part = name.partition("_solid_")
        if group not in ("K", "M") or part != info.get("complement"):
            known = sorted(self.solids) + ([f"K_solid_{info['complement']}", f"M_solid_{info['complement']}"]
                                           if info.get("complement") else [])
            raise KeyError(f"no term named {name!r}; the model's solid terms are {known or 'none'}")
        total = (self.stiffness["K0"] if group == "K" else self.mass["M0"]).tocsr()
        rest = [A for n, A in self.solids.items() if n.startswith(f"{group}_solid_")]
        return (total - sum(rest[1:], rest[0])).tocsr() if rest else total.copy()


def _affine_sum(terms: dict[str, sp.csr_matrix], base: str, coeffs: dict[str, float],
                other=None) -> sp.csr_matrix:
    """``terms[base] + sum coeffs[name] * terms[name]``.  The affine terms (joint layers, masses on
    patches) touch few DOFs: summed among themselves first, the large base matrix is added once
    (one pass over its entries instead of one per term).  ``other(name)`` gives a term not in
    ``terms`` (the solids of :class:`Model`)."""
    extra = None
    for name, c in coeffs.items():
        if c != 0.0:
            t = c * (terms[name] if name in terms or other is None else other(name))
            extra = t if extra is None else extra + t
    return (terms[base] + extra).tocsr() if extra is not None else terms[base].copy().tocsr()


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lamé constants (lambda, mu) in Pa from Young's modulus [Pa] and Poisson's ratio."""
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


def _vector_from_scalar_blocks(blocks, n):
    """Interleave 3x3 scalar blocks ``blocks[c][d]`` (n x n) into a (3n x 3n) matrix: entry ``(i, j)`` of
    block ``(c, d)`` goes to ``(3i + c, 3j + d)``.

    Blocks summed from one element list share one sparsity pattern (CSR, duplicates summed): the result's
    index arrays then follow from that pattern and each value is moved, not added again, so the matrix holds
    the same bits as the general path below (a COO of all nine blocks converted to CSR) in a fifth of its
    time (``tests/test_fem.py``)."""
    B = [[blocks[c][d] for d in range(3)] for c in range(3)]
    ip, ix = B[0][0].indptr, B[0][0].indices
    if not all(sp.isspmatrix_csr(b) and b.has_canonical_format and np.array_equal(b.indptr, ip)
               and np.array_equal(b.indices, ix) for row in B for b in row):
        return _vector_from_coo(B, n)
    cnt = np.diff(ip).astype(np.int64)
    nnz = len(ix)
    row_of = np.repeat(np.arange(n, dtype=np.int64), cnt)
    within = np.arange(nnz, dtype=np.int64) - ip[row_of]
    start = 9 * ip[row_of].astype(np.int64) + 3 * within  # position of (k, c=0, d=0) in the result
    itype = np.int32 if 9 * nnz < np.iinfo(np.int32).max else np.int64
    data = np.empty(9 * nnz)
    indices = np.empty(9 * nnz, dtype=itype)
    for c in range(3):
        base = start + 3 * c * cnt[row_of]
        for d in range(3):
            data[base + d] = B[c][d].data
            indices[base + d] = 3 * ix + d
    indptr = np.empty(3 * n + 1, dtype=itype)
    indptr[:-1] = (9 * ip[:-1].astype(np.int64)[:, None] + 3 * np.arange(3) * cnt[:, None]).ravel()
    indptr[-1] = 9 * nnz
    out = sp.csr_matrix((data, indices, indptr), shape=(3 * n, 3 * n))
    out.has_sorted_indices = True
    return out


def _vector_from_coo(blocks, n):
    """:func:`_vector_from_scalar_blocks` of blocks of any patterns: one COO, converted to CSR."""
    rows, cols, vals = [], [], []
    for c in range(3):
        for d in range(3):
            B = blocks[c][d].tocoo()
            rows.append(3 * B.row + c)
            cols.append(3 * B.col + d)
            vals.append(B.data)
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(3 * n, 3 * n))


def assemble_elasticity(basis: Basis, lam_e: np.ndarray, mu_e: np.ndarray, rho_e: np.ndarray,
                        chunk: int = 4000, elements: np.ndarray | None = None
                        ) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Stiffness and consistent mass of isotropic solids with per-element constants.

    ``basis`` is a *scalar* basis; returns vector-valued (3N x 3N) K and M.  Element matrices are
    built in chunks with einsum: G_ab = int d_a(phi_i) d_b(phi_j) dx, then
    K_cd = lam G_cd + mu G_dc + mu delta_cd sum_e G_ee.  ``elements`` (indices) assembles only those
    elements (one part of the solids, e.g. the terms ``K_solid_<part>`` of
    :func:`jointid.fe.model.build_model`); the matrices keep the full size.
    """
    n = basis.N
    dofs = basis.element_dofs  # (nloc, nel)
    nloc, nel = dofs.shape
    grads = np.stack([basis.basis[i][0].grad for i in range(nloc)])  # (nloc, 3, nel, nqp)
    vals = np.stack([np.asarray(basis.basis[i][0]) for i in range(nloc)])  # (nloc, nel, nqp)
    dx = basis.dx  # (nel, nqp)
    sel = np.arange(nel) if elements is None else np.asarray(elements, dtype=np.int64)
    if len(sel) == 0:
        return sp.csr_matrix((3 * n, 3 * n)), sp.csr_matrix((3 * n, 3 * n))
    parts = [[[] for _ in range(3)] for _ in range(3)]
    mparts, rparts, cparts = [], [], []
    for s in range(0, len(sel), chunk):
        e = sel[s: s + chunk] if elements is not None else slice(s, min(nel, s + chunk))
        g = grads[:, :, e, :]
        w = dx[e]
        G = np.einsum("iaeq,jbeq,eq->abije", g, g, w, optimize=True)  # (3, 3, i, j, e)
        trace = G[0, 0] + G[1, 1] + G[2, 2]
        lam, mu = lam_e[e], mu_e[e]
        for c in range(3):
            for d in range(3):
                blk = lam * G[c, d] + mu * G[d, c]
                if c == d:
                    blk = blk + mu * trace
                parts[c][d].append(blk.reshape(-1))
        Me = np.einsum("ieq,jeq,eq->ije", vals[:, e], vals[:, e], w * rho_e[e][:, None], optimize=True)
        mparts.append(Me.reshape(-1))
        de = dofs[:, e]
        rparts.append(np.broadcast_to(de[:, None, :], (nloc, nloc, de.shape[1])).reshape(-1))
        cparts.append(np.broadcast_to(de[None, :, :], (nloc, nloc, de.shape[1])).reshape(-1))
    r, cidx = np.concatenate(rparts), np.concatenate(cparts)
    values = [[np.concatenate(parts[c][d]) for d in range(3)] for c in range(3)]
    to_csr = _coo_summer(r, cidx, n, values[0][0])
    Kb = [[to_csr(values[c][d]) for d in range(3)] for c in range(3)]
    K = _vector_from_scalar_blocks(Kb, n)
    Ms = to_csr(np.concatenate(mparts))
    M = sp.kron(Ms, sp.eye(3), format="csr")
    return K, M


def _coo_summer(r: np.ndarray, c: np.ndarray, n: int, first: np.ndarray):
    """A function that turns values at the COO coordinates ``(r, c)`` into the CSR matrix
    ``sp.csr_matrix((values, (r, c)), shape=(n, n))`` would give, bit for bit.

    The blocks and the mass of one assembly share their coordinates, so the order in which scipy adds the
    duplicates (its CSR rows in input order, each row sorted by ``csr_sort_indices``, then added from the
    left) is found once, from a probe of positions, and replayed on each block: a gather and at most a few
    vector additions instead of a conversion and a sort per block.  The replay is checked on ``first``
    against scipy's own conversion; where it would differ, every block is converted by scipy."""
    ref = sp.csr_matrix((first, (r, c)), shape=(n, n))
    order = np.argsort(r, kind="stable")
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(r, minlength=n), out=indptr[1:])
    probe = sp.csr_matrix((order.astype(np.float64), c[order], indptr), shape=(n, n))
    probe.has_sorted_indices = False
    probe.sort_indices()  # the sort scipy's sum_duplicates does, on the positions
    src = probe.data.astype(np.int64)
    rows = np.repeat(np.arange(n), np.diff(indptr))
    new = np.ones(len(src), dtype=bool)
    new[1:] = (probe.indices[1:] != probe.indices[:-1]) | (rows[1:] != rows[:-1])
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, len(src)))
    later = [(np.flatnonzero(counts > t), starts[counts > t] + t) for t in range(1, int(counts.max(initial=1)))]

    def summed(values: np.ndarray) -> sp.csr_matrix:
        v = values[src]
        out = v[starts]  # a copy: each sum starts from its first value, then adds the rest in turn
        for at, pos in later:
            out[at] += v[pos]
        m = sp.csr_matrix((out, ref.indices.copy(), ref.indptr.copy()), shape=(n, n))
        m.has_sorted_indices = True
        m.has_canonical_format = True
        return m

    first_replayed = summed(first)
    if len(starts) != ref.nnz or first_replayed.data.tobytes() != ref.data.tobytes():
        return lambda values: sp.csr_matrix((values, (r, c)), shape=(n, n))
    return lambda values: ref if values is first else summed(values)


def facet_mass(mesh, elem, facets: np.ndarray, intorder: int) -> sp.csr_matrix:
    """Scalar facet mass matrix ``int_F phi_i phi_j dA`` over the given facets (N x N)."""
    if len(facets) == 0:
        return sp.csr_matrix((Basis(mesh, elem, intorder=1).N,) * 2)
    fb = FacetBasis(mesh, elem, facets=facets, intorder=intorder)

    @BilinearForm
    def mass(u, v, w):
        return u * v

    S = mass.assemble(fb).tocsr()
    S.data[np.abs(S.data) < 1e-14 * np.abs(S.data).max()] = 0.0  # off-facet dofs: round-off only
    S.eliminate_zeros()
    return S


def jump_operator(S: sp.csr_matrix, doflocs: np.ndarray, direction: int,
                  dof_body: np.ndarray | None = None) -> sp.csr_matrix:
    """Jump ``u_side - u_partner`` in one direction for the facet dofs of ``S``.

    The partner of each facet dof is a dof of the other body at the same location (duplicated node);
    ``dof_body`` (body of each scalar dof) tells the bodies apart where one body has several dofs at
    one place (hanging nodes, ``jointid.geometry.localrefine``).  Returns D with shape (N, 3N).
    """
    n = S.shape[0]
    rowsum = np.asarray(abs(S).sum(axis=1)).ravel()
    active = np.flatnonzero(rowsum > 1e-10 * rowsum.max())
    tree = cKDTree(doflocs.T)
    k = 2 if dof_body is None else 16  # hanging nodes: a few dofs of one body may share a place
    dist, idx = tree.query(doflocs[:, active].T, k=k)
    if dof_body is None:
        other = idx != active[:, None]
    else:
        other = dof_body[np.minimum(idx, n - 1)] != dof_body[active][:, None]
    first = np.argmax(other, axis=1)
    rows_ = np.arange(len(active))
    partner = idx[rows_, first]
    d_partner = np.where(other[rows_, first], dist[rows_, first], np.inf)
    scale = np.ptp(doflocs, axis=1).max()
    if np.any(d_partner > 1e-9 * scale):
        raise ValueError("joint face dofs without a partner on the other body: mesh interface is broken")
    rows = np.concatenate([active, active])
    cols = np.concatenate([3 * active + direction, 3 * partner + direction])
    vals = np.concatenate([np.ones(len(active)), -np.ones(len(active))])
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, 3 * n))


def spring_layer(S: sp.csr_matrix, doflocs: np.ndarray, direction: int,
                 dof_body: np.ndarray | None = None) -> sp.csr_matrix:
    """Unit (1 N/m^3) spring layer ``D^T S D`` between the two bodies in one direction."""
    D = jump_operator(S, doflocs, direction, dof_body)
    return (D.T @ S @ D).tocsr()


def vector_rows(P: sp.spmatrix) -> sp.csr_matrix:
    """Scalar interpolation rows ``(n_pts, N)`` -> vector rows ``(3 n_pts, 3 N)`` ordered (point,
    direction), the layout of ``Model.probe``."""
    Pc = sp.coo_matrix(P)
    n_pts, n = P.shape
    return sp.csr_matrix((np.tile(Pc.data, 3), (np.concatenate([3 * Pc.row + c for c in range(3)]),
                                                 np.concatenate([3 * Pc.col + c for c in range(3)]))),
                         shape=(3 * n_pts, 3 * n))


def ground_springs(S: sp.csr_matrix) -> sp.csr_matrix:
    """Unit springs per area to the ground in all three directions: kron(S, I3)."""
    return sp.kron(S, sp.eye(3), format="csr")


def surface_mass(S: sp.csr_matrix) -> sp.csr_matrix:
    """A 1 kg mass layer spread uniformly over the facets of ``S`` (vector, consistent)."""
    area = S.sum()
    return sp.kron(S / area, sp.eye(3), format="csr")
