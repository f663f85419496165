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

__all__ = ["AffineModel"]


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
