"""Storage of a growing subspace basis and its products with the two base terms.

The columns live in Fortran-ordered buffers that double when full, so appending copies nothing
already stored.  ``K0 V`` and ``M0 V`` are kept beside ``V`` while the two products fit in
:data:`BASE_PRODUCT_BYTES`: a full-space residual ``K(c) V y - lambda M(m) V y`` then needs neither
an assembly nor a product with the whole stiffness (the other terms touch few rows).
"""

from __future__ import annotations

import numpy as np

BASE_PRODUCT_BYTES = 1.5e9
"""Largest memory for the cached products ``K0 V`` and ``M0 V`` together (beyond it: sparse products)."""


class GrowingBasis:
    """``V (n, r)`` with the products ``K0 V`` and ``M0 V`` (None once they no longer fit)."""

    def __init__(self, n: int):
        self.r = 0
        self._V = np.zeros((n, 0), order="F")
        self._KV = self._MV = None
        self.keep_products = True

    @property
    def V(self) -> np.ndarray:
        return self._V[:, : self.r]

    @property
    def KV(self) -> np.ndarray | None:
        return None if self._KV is None else self._KV[:, : self.r]

    @property
    def MV(self) -> np.ndarray | None:
        return None if self._MV is None else self._MV[:, : self.r]

    def adopt(self, V: np.ndarray, KV: np.ndarray, MV: np.ndarray) -> None:
        """Take ``V`` (Fortran order, the first columns of an empty basis) and its products as they are."""
        self.r = V.shape[1]
        self._V = np.asfortranarray(V)
        self.keep_products = 2 * self.r * V.shape[0] * 8 <= BASE_PRODUCT_BYTES
        self._KV, self._MV = (np.asfortranarray(KV), np.asfortranarray(MV)) if self.keep_products else (None, None)

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
        self.keep_products = self.keep_products and 2 * cap * n * 8 <= BASE_PRODUCT_BYTES
        self._V = self._copy(self._V, cap)
        if self.keep_products:
            self._KV = self._copy(self._KV, cap) if self._KV is not None else np.zeros((n, cap), order="F")
            self._MV = self._copy(self._MV, cap) if self._MV is not None else np.zeros((n, cap), order="F")
        else:
            self._KV = self._MV = None

    def _copy(self, B: np.ndarray, cap: int) -> np.ndarray:
        N = np.zeros((B.shape[0], cap), order="F")
        N[:, : self.r] = B[:, : self.r]
        return N
