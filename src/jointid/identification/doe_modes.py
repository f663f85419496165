"""The modes of every DOE point from one reduced basis (``solver.method: reduced``).

One :class:`jointid.fe.reduced.ReducedSolver` is started at the centre of the points (the geometric
mean of each joint parameter over the sheet): the exact modes there and their first-order
responses to each joint parameter.  Each point is then answered on that basis, which grows where
the point needs it: a Ritz pair counts only once its full-space residual says its eigenvalue is
within the solver tolerance (1e-6 relative); otherwise preconditioned residuals join the basis, and
after :data:`jointid.fe.certify.MAX_ROUNDS` rounds the full solve answers and says so in the log.
The answers are full-FE answers to that tolerance, for one factorisation instead of one shift-invert
Lanczos run per point.  ``solver.method: full`` is the reference path (``tests/test_doe_modes.py``
compares the two).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from jointid.config.typed import ModelSpec
from jointid.fe.describe import describe_modes
from jointid.fe.model import base_coefficients, joint_terms
from jointid.fe.reduced import ReducedSolver


@dataclass
class PointModes:
    """The modes of one DOE point: frequencies (Hz), shapes at the measuring points
    ``(n_labels, n_modes)``, the energy table (:func:`jointid.fe.describe.describe_modes`), the largest
    estimated relative eigenvalue error of its certificate and the basis size that answered it."""

    freqs_Hz: np.ndarray
    shapes: np.ndarray
    description: pd.DataFrame
    error: float
    basis_size: int


def centre(thetas: list[dict[str, float]]) -> dict[str, float]:
    """The geometric mean of each parameter over ``thetas`` (the DOE is laid out in log-parameters)."""
    return {n: float(np.exp(np.mean([np.log(th[n]) for th in thetas]))) for n in thetas[0]}


def solve_points(spec: ModelSpec, model, thetas: list[dict[str, float]], *, log=None):
    """Yield :class:`PointModes` for each of ``thetas`` (joint parameters in N/m^3), in order.

    ``spec.solver`` gives the number of modes, the shift and the backend; ``log``: where the
    solver's fallbacks to the full solve are reported.
    """
    s = spec.solver
    jt = joint_terms(spec.joints, spec.mesh_file)
    directions = [({t: 1.0 for t in jt[name]}, {}) for name in thetas[0]]
    kc0, mc0 = base_coefficients(spec, model, centre(thetas))
    rs = ReducedSolver(model, kc0, mc0, s.n_modes, directions, shift_Hz=s.shift_Hz, backend=s.backend)
    rs.log = log
    for theta in thetas:
        kc, mc = base_coefficients(spec, model, theta)
        sol = rs.solve(kc, mc, s.n_modes)
        phi = rs.full_phi(sol)
        yield PointModes(sol.freqs_Hz, model.probe @ phi, describe_modes(model, phi, kc, mc), float(sol.error),
                         int(rs.basis.r))
