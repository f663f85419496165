"""The affine matrices of a model on its free DOFs, assembled on one fixed sparsity pattern.

``K(c) = K0 + sum c_a K_a`` and ``M(m) = M0 + sum m_b M_b`` (a :class:`jointid.fe.affine.AffineModel`: the FE
model, or the diagnosis's with its effect terms) change only in their coefficients
from one parameter point to the next.  :class:`FreePencil` restricts every term to the free DOFs once,
places all of them on the union of their sparsity patterns, and then assembles the stiffness at new
coefficients as one scatter-add per term into that pattern: no sparse additions, no slicing and no
triangle extraction per point (the mass, a third of the pattern, keeps its own).  ``shifted_upper`` gives the upper triangle of ``K - sigma M`` that
the sparse Cholesky backend factorises, with the same pattern at every point (its fill-reducing
ordering can be reused: :attr:`FreePencil.ordering`).
"""

from __future__ import annotations

import threading

import numpy as np
import scipy.sparse as sp

from jointid.fe.modal import free_dofs, release_model_pages, restrict


class FreePencil:
    """``K(c)``, ``M(m)`` and ``K - sigma M`` of an affine model on its free DOFs.

    Parameters
    ----------
    system : jointid.fe.affine.AffineModel
        Anything with ``stiffness`` and ``mass`` term dicts (``K0``, ``M0`` included), ``fixed`` and
        ``n_dofs``.

    Attributes
    ----------
    free : ndarray
        Free (unclamped) DOFs; the matrices act on ``u[free]``.
    K_terms, M_terms : dict of csr_matrix
        The terms restricted to the free DOFs (for projections onto a subspace).
    ordering : ndarray or None
        Fill-reducing ordering of the pattern found by the first factorisation (set by
        :func:`jointid.fe.modal.factorize_pencil`), reused by later ones.
    """

    def __init__(self, system):
        self.n_dofs = system.n_dofs
        self.free = free_dofs(system.n_dofs, system.fixed)
        self.K_terms = {k: restrict(A, self.free) for k, A in system.stiffness.items()}
        self.M_terms = {k: restrict(A, self.free) for k, A in system.mass.items()}
        for A in (*self.K_terms.values(), *self.M_terms.values()):
            A.sum_duplicates()
            A.sort_indices()
        release_model_pages(system)  # the terms are copied: the model file's pages are not needed
        self.ordering = getattr(system, "ordering", None)  # cached with the model, if it was
        self._lock = threading.Lock()
        self._laid_out = False

    def layout(self) -> None:
        """Place the terms on the union of their patterns (once; thread-safe): what every assembly needs
        (:meth:`K`, :meth:`shifted_upper`).  ``K_terms["K0"]`` is then the same matrix aligned with that
        pattern.  Made when first needed, so that a caller may have it made in a background thread
        (:class:`jointid.fe.reduced.ReducedSolver` ``prefactor``); a caller that multiplies by
        ``K_terms["K0"]`` asks for it first, so that it always multiplies by the aligned matrix."""
        if self._laid_out:
            return
        with self._lock:
            if not self._laid_out:
                self._lay_out()
                self._laid_out = True

    def _lay_out(self) -> None:
        self.pattern = _union_pattern([*self.K_terms.values(), *self.M_terms.values()])
        # K0 (nearly the whole pattern) is kept aligned with the pattern, and is the stiffness term
        # K0 itself (no second copy): assembling is one copy plus a scatter of the few entries of
        # each other term (the mass terms, M0 included, are scattered: a third of the pattern)
        self._pos = {}
        keys = _keys(self.pattern)  # once: every term is located by a search in these
        for group, terms in (("K", self.K_terms), ("M", self.M_terms)):
            for k, A in terms.items():
                pos = _positions(keys, A)
                if (group, k) == ("K", "K0"):
                    self._K0 = np.zeros(self.pattern.nnz)
                    self._K0[pos] = A.data
                else:
                    self._pos[(group, k)] = pos
        self.K_terms["K0"] = self._csr(self._K0)
        P = self.pattern
        rows = np.repeat(np.arange(P.shape[0]), np.diff(P.indptr))
        upper = P.indices >= rows
        self._upper = np.flatnonzero(upper).astype(np.int32 if P.nnz < 2**31 else np.int64)
        counts = np.bincount(rows[upper], minlength=P.shape[0])
        indptr = np.zeros(P.shape[0] + 1, dtype=P.indptr.dtype)
        np.cumsum(counts, out=indptr[1:])
        self._upper_indices, self._upper_indptr = P.indices[upper], indptr

    @property
    def n_free(self) -> int:
        return len(self.free)

    def _data(self, group: str, coeffs: dict[str, float], scale: float = 1.0, out=None) -> np.ndarray:
        self.layout()
        terms = self.K_terms if group == "K" else self.M_terms
        base = "K0" if group == "K" else "M0"
        unknown = set(coeffs) - set(terms)
        if unknown:
            raise KeyError(f"no {group} term named {sorted(unknown)}; the model has {sorted(terms)}")
        c0 = scale * (1.0 + coeffs.get(base, 0.0))
        if group == "K":
            data = np.multiply(self._K0, c0) if out is None else np.add(out, self._K0 * c0, out=out)
        else:
            data = np.zeros(self.pattern.nnz) if out is None else out
            data[self._pos[("M", "M0")]] += c0 * terms["M0"].data
        for name, c in coeffs.items():
            if name != base and c != 0.0:
                data[self._pos[(group, name)]] += (scale * c) * terms[name].data
        return data

    def _csr(self, data: np.ndarray) -> sp.csr_matrix:
        P = self.pattern
        return sp.csr_matrix((data, P.indices, P.indptr), shape=P.shape)

    def K(self, kc: dict[str, float]) -> sp.csr_matrix:
        """Stiffness on the free DOFs at coefficients ``kc`` (``K0`` always included)."""
        return self._csr(self._data("K", kc))

    def M(self, mc: dict[str, float]) -> sp.csr_matrix:
        """Mass on the free DOFs at coefficients ``mc`` (``M0`` always included), on the mass terms'
        own pattern: the mass of solids couples only like components, a third of the stiffness
        pattern, and every eigen-solver step multiplies by it."""
        out = self.M_terms["M0"] * (1.0 + mc.get("M0", 0.0))
        for name, c in mc.items():
            if name not in self.M_terms:
                raise KeyError(f"no M term named {name!r}; the model has {sorted(self.M_terms)}")
            if name != "M0" and c != 0.0:
                out = out + c * self.M_terms[name]
        return out.tocsr()

    def shifted(self, kc: dict[str, float], mc: dict[str, float], sigma: float) -> sp.csr_matrix:
        """``K(kc) - sigma M(mc)`` on the free DOFs (both triangles)."""
        return self._csr(self._data("M", mc, -sigma, self._data("K", kc)))

    def shifted_upper(self, kc: dict[str, float], mc: dict[str, float], sigma: float) -> sp.csr_matrix:
        """Upper triangle (diagonal included, sorted indices) of ``K(kc) - sigma M(mc)``."""
        data = self._data("M", mc, -sigma, self._data("K", kc))[self._upper]
        A = sp.csr_matrix((data, self._upper_indices, self._upper_indptr), shape=self.pattern.shape)
        A.has_sorted_indices = True
        return A

    def expand(self, vec: np.ndarray) -> np.ndarray:
        """Full-size vectors (zeros at the fixed DOFs) from free-DOF vectors (rows)."""
        out = np.zeros((self.n_dofs,) + vec.shape[1:])
        out[self.free] = vec
        return out


def _union_pattern(mats: list[sp.csr_matrix]) -> sp.csr_matrix:
    """The union of the sparsity patterns (sorted CSR, data all ones).  The small terms are gathered
    into one matrix first, so the large ones are added once, not once per term."""
    def ones(A):
        return sp.csr_matrix((np.ones(A.nnz), A.indices, A.indptr), shape=A.shape)

    big = sorted(mats, key=lambda A: A.nnz, reverse=True)
    large, small = big[:2], big[2:]
    U = ones(large[0])
    for A in large[1:]:
        U = U + ones(A)
    if small:
        rows = np.concatenate([np.repeat(np.arange(A.shape[0]), np.diff(A.indptr)) for A in small])
        cols = np.concatenate([A.indices for A in small])
        U = U + sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=U.shape)
    U = U.tocsr()
    U.sum_duplicates()
    U.sort_indices()
    U.data[:] = 1.0
    return U


def _keys(P: sp.csr_matrix) -> np.ndarray:
    """Sorted linear keys ``row * n_cols + col`` of the stored entries of a sorted CSR pattern."""
    prow = np.repeat(np.arange(P.shape[0], dtype=np.int64), np.diff(P.indptr))
    return prow * P.shape[1] + P.indices


def _positions(pkeys: np.ndarray, A: sp.csr_matrix) -> np.ndarray:
    """Index into the pattern's data of every stored entry of ``A`` (A's pattern is a subset of the
    pattern whose :func:`_keys` are ``pkeys``)."""
    arow = np.repeat(np.arange(A.shape[0], dtype=np.int64), np.diff(A.indptr))
    pos = np.searchsorted(pkeys, arow * A.shape[1] + A.indices)
    dtype = np.int32 if len(pkeys) < 2**31 else np.int64
    return pos.astype(dtype)
