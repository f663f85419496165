"""Storage of a growing subspace basis and its products with the two base terms.

The columns live in Fortran-ordered buffers that double when full, so appending copies nothing
already stored.  ``K0 V`` and ``M0 V`` are kept beside ``V`` while the two products fit in
:data:`BASE_PRODUCT_BYTES`: a full-space residual ``K(c) V y - lambda M(m) V y`` then needs neither
an assembly nor a product with the whole stiffness (the other terms touch few rows).

A basis taken over from an earlier run may have them *deferred* (:meth:`GrowingBasis.adopt` without
products; the diagnosis's rerun, :class:`jointid.fe.reduced.ReducedSolver` ``defer_products``): the
few checks of a rerun multiply by the sparse terms instead (about 0.08 s more per
check of two states on the default mesh, against about 3.3 core-seconds to form both products of
448 vectors), and the solver forms them when its checks become many
(:data:`jointid.fe.reduced.CHECKS_BEFORE_PRODUCTS`).

The products are stored in single precision (:data:`PRODUCT_DTYPE`): they enter only the residual
check (:mod:`jointid.fe.certify`), whose estimate ``r^T A^-1 r / lambda`` then carries an absolute
error of order 1e-12 (eps32^2 times a few hundred for the sums) and a relative one of order 1e-3 at
the tolerance 1e-6, far inside what a check decides; the Ritz values themselves come from the
double-precision reduced matrices.  Single precision halves the products' memory and the time of
the largest dense products of a check.
"""

from __future__ import annotations

import numpy as np

BASE_PRODUCT_BYTES = 1.5e9
"""Largest memory for the cached products ``K0 V`` and ``M0 V`` together (beyond it: sparse products)."""
PRODUCT_DTYPE = np.float32
"""Storage of the cached products (see the module notes)."""


class GrowingBasis:
    """``V (n, r)`` with the products ``K0 V`` and ``M0 V`` (None once they no longer fit)."""

    def __init__(self, n: int):
        self.r = 0
        self._V = np.zeros((n, 0), order="F")
        self._KV = self._MV = None
        self.keep_products = True
        self.deferred = False  # products not formed yet for a basis taken over (see adopt)

    @property
    def V(self) -> np.ndarray:
        return self._V[:, : self.r]

    @property
    def KV(self) -> np.ndarray | None:
        return None if self._KV is None else self._KV[:, : self.r]

    @property
    def MV(self) -> np.ndarray | None:
        return None if self._MV is None else self._MV[:, : self.r]

    def adopt(self, V: np.ndarray, KV: np.ndarray | None = None, MV: np.ndarray | None = None) -> None:
        """Take ``V`` (Fortran order, the first columns of an empty basis) and its products as they are;
        without products they are deferred (:meth:`form_products` forms them)."""
        self.r = V.shape[1]
        self._V = np.asfortranarray(V)
        self.keep_products = 2 * self.r * V.shape[0] * _ITEM <= BASE_PRODUCT_BYTES
        self.deferred = self.keep_products and (KV is None or MV is None)
        self._KV, self._MV = ((np.asfortranarray(KV, dtype=PRODUCT_DTYPE), np.asfortranarray(MV, dtype=PRODUCT_DTYPE))
                              if self.keep_products and not self.deferred else (None, None))

    def form_products(self, KV: np.ndarray, MV: np.ndarray) -> None:
        """End the deferral: the products of all ``r`` columns (:func:`stored_product`), placed in buffers
        of the basis's capacity (later columns append their own)."""
        self.deferred = False
        if not self.keep_products:
            return
        n, cap = self._V.shape
        self._KV, self._MV = _zeros(n, cap, PRODUCT_DTYPE), _zeros(n, cap, PRODUCT_DTYPE)
        self._KV[:, : self.r], self._MV[:, : self.r] = KV, MV

    def append(self, W: np.ndarray, KW: np.ndarray | None, MW: np.ndarray | None) -> None:
        """Append the columns ``W`` with their products ``K0 W`` and ``M0 W`` (given when kept)."""
        k = W.shape[1]
        self._grow(k)
        r0 = self.r
        self._V[:, r0: r0 + k] = W
        if self._KV is not None:
            self._KV[:, r0: r0 + k] = KW
            self._MV[:, r0: r0 + k] = MW
        self.r = r0 + k

    def _grow(self, extra: int) -> None:
        n, cap0 = self._V.shape
        if self.r + extra <= cap0:
            return
        cap = max(self.r + extra, 2 * cap0, 64)
        self.keep_products = self.keep_products and 2 * cap * n * _ITEM <= BASE_PRODUCT_BYTES
        self.deferred = self.deferred and self.keep_products
        self._V = self._copy(self._V, cap)
        if self.keep_products and not self.deferred:
            self._KV = self._copy(self._KV, cap) if self._KV is not None else _zeros(n, cap, PRODUCT_DTYPE)
            self._MV = self._copy(self._MV, cap) if self._MV is not None else _zeros(n, cap, PRODUCT_DTYPE)
        else:
            self._KV = self._MV = None

    def _copy(self, B: np.ndarray, cap: int) -> np.ndarray:
        N = _zeros(B.shape[0], cap, B.dtype)
        N[:, : self.r] = B[:, : self.r]
        return N

    def product(self, group: str, Y: np.ndarray) -> np.ndarray | None:
        """``K0 V Y`` (``group`` "K") or ``M0 V Y`` ("M") from the cached single-precision product, in
        double precision (None when the products are not kept, or deferred)."""
        cached = self.KV if group == "K" else self.MV
        if cached is None:
            return None
        return (cached @ np.asarray(Y, dtype=PRODUCT_DTYPE)).astype(np.float64)


_ITEM = np.dtype(PRODUCT_DTYPE).itemsize
PRODUCT_BLOCK = 64
"""Columns per sparse product in :func:`stored_product`."""


def stored_product(A, V: np.ndarray) -> np.ndarray:
    """``A V`` as the basis stores it (:data:`PRODUCT_DTYPE`, Fortran order), formed in double precision
    :data:`PRODUCT_BLOCK` columns at a time: the same bits as ``(A @ V).astype(PRODUCT_DTYPE)`` (each output
    column is its own sum), without a double-precision copy of the whole product and its transposition
    (on the default mesh, 448 vectors: about a fifth less time)."""
    out = np.empty(V.shape, dtype=PRODUCT_DTYPE, order="F")
    for j in range(0, V.shape[1], PRODUCT_BLOCK):
        out[:, j: j + PRODUCT_BLOCK] = A @ np.ascontiguousarray(V[:, j: j + PRODUCT_BLOCK])
    return out


def _zeros(n: int, cap: int, dtype) -> np.ndarray:
    return np.zeros((n, cap), dtype=dtype, order="F")
