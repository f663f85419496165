"""Mode-shape residuals of the diagnosis's fits (issue 40, item 1; docs/effects.md, "Shapes in the fit").

Where a state has measured shapes, each measured mode adds, after all the frequency rows of the
evaluation, the modal-displacement residual after best scaling, one row per measured point and direction:

    r = (alpha phi - psi) / eps,     alpha = phi^T psi / phi^T phi,

``psi`` the measured shape at its measured DOFs scaled to a noise-free RMS of one (its RMS divided by
``sqrt(1 + eps^2)``), ``phi`` the paired model mode there, ``eps`` the shape uncertainty
(``shape_uncertainty_pct / 100`` of conditions.yaml: the 1-sigma noise of each modal displacement as a
fraction of the RMS of the mode's noise-free displacements over its measured DOFs).  ``alpha`` takes
the arbitrary scale and sign of a measured shape (one nuisance parameter per mode, counted off the
residual rows: :attr:`Evaluation.n_scales`).

Why this and not ``1 - MAC`` as one row per mode: the two carry the same information,
``sum r^2 = |psi|^2 (1 - MAC) / eps^2``, but ``1 - MAC`` is not a zero-mean residual (at the truth it is
about ``eps^2`` with a spread of ``eps^2 sqrt(2 / n)``), so a chi-square, its p-value and AICc built from it
are wrong, and its derivative vanishes at MAC = 1 (Gauss-Newton stalls).  The displacement residual is
Gaussian with unit variance per row, so chi-square, AICc and the score tests keep their meaning.

Sensitivities are exact for the reduced model (:func:`jointid.fe.shape_derivative.probe_shape_derivatives`,
Nelson's method on the subspace), less the rotation between modes closer than 0.5 % in frequency
(:data:`jointid.fe.shape_derivative.CLOSE_MODE_GAP`).  A measured mode without a model partner keeps its rows with the
model's part zero (``alpha = 0``: MAC 0), so the number of rows never depends on the pairing.
Where the mesh error is in the budget (:mod:`jointid.diagnosis.mesh_error`), the model shapes are
corrected by the refined meshes' change of them, and each row carries the size of that change as a known
error beside ``eps``.  The shape rows are judged as a block of their own, with their own model error
(:func:`jointid.diagnosis.results.block_error`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from jointid.correlate.shape_rows import (MIN_SHAPE_UNCERTAINTY, normalised_shape, scaled_residual,
                                          shape_noise_estimate)
from jointid.diagnosis.mesh_error import shape_known
from jointid.fe.shape_derivative import probe_shape_derivatives

__all__ = ["ShapeBlock", "ShapeTerms", "normalised_shape", "shape_block", "estimate_shape_uncertainty"]



class ShapeBlock:
    """Shape residual rows of one evaluation: ``r (n,)``, ``J (n, p)``, ``rows`` ((state, -mode) per row),
    ``n_scales`` (one best scale per measured mode with a shape)."""

    def __init__(self, p: int):
        self.r, self.J, self.known, self.rows, self.n_scales = [], [], [], [], 0
        self.p = p

    def add(self, si: int, mode: int, r: np.ndarray, J: np.ndarray, known: np.ndarray | None = None) -> None:
        self.r.append(r)
        self.J.append(J)
        self.known.append(np.zeros(len(r)) if known is None else np.asarray(known, float))
        self.rows += [(si, -(mode + 1))] * len(r)
        self.n_scales += 1

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        if not self.r:
            return np.zeros(0), np.zeros((0, self.p))
        return np.concatenate(self.r), np.vstack(self.J)

    def known_errors(self) -> np.ndarray:
        """The known error of every row (the mesh's, relative to its mode's RMS; zeros where none)."""
        return np.concatenate(self.known) if self.known else np.zeros(0)


def shape_block(solver, data, sols, index, directions: list, eps: dict) -> ShapeBlock:
    """Shape residual rows of every state with shapes (states in ``eps``, state number -> uncertainty).

    ``directions`` per state: the coefficient derivatives ``(dkc, dmc)`` of the Jacobian's columns.
    """
    p = len(directions[0]) if directions else 0
    block = ShapeBlock(p)
    for si, (d, sol, idx) in enumerate(zip(data, sols, index)):
        if si not in eps or d.shapes is None:
            continue
        idx = np.asarray(idx, int)
        measured = [m for m in range(d.shapes.shape[1]) if np.isfinite(d.shapes[:, m]).any()]
        paired = [m for m in measured if idx[m] >= 0]
        dphi = (probe_shape_derivatives(solver, sol, [int(idx[m]) for m in paired], directions[si])
                if paired and p else None)
        for m in measured:
            ok = np.isfinite(d.shapes[:, m])
            psi = normalised_shape(d.shapes[ok, m], eps[si])
            if idx[m] >= 0:
                k = paired.index(m)
                dp = dphi[ok, k, :] if dphi is not None else np.zeros((int(ok.sum()), p))
                r, J = scaled_residual(psi, sol.shapes[ok, idx[m]], dp, eps[si])
                known = shape_known(d, sol.shapes, ok, int(idx[m]))
            else:
                r, J, known = -psi / eps[si], np.zeros((len(psi), p)), None
            block.add(si, m, r, J, known)
    return block


def estimate_shape_uncertainty(data, sols, index) -> float:
    """One shape uncertainty for the states given (``data``/``sols``/``index`` aligned) from the misfit of
    their paired modes (:func:`jointid.correlate.shape_rows.shape_noise_estimate`): an upper bound of
    the noise."""
    pairs = []
    for d, sol, idx in zip(data, sols, index):
        for m in range(d.shapes.shape[1]):
            ok = np.isfinite(d.shapes[:, m])
            if idx[m] >= 0:
                pairs.append((d.shapes[ok, m], sol.shapes[ok, idx[m]]))
    return shape_noise_estimate(pairs)


class ShapeTerms:
    """The shape rows of one :class:`jointid.diagnosis.fitting.Diagnoser`: which states carry them and at
    which uncertainty.

    Active for the states with a measured shape unless ``diagnosis.shape_residuals`` is false.  The
    uncertainty of a state is its dataset's ``shape_uncertainty_pct`` (:class:`StateData`
    ``shape_sigma_rel``); where that is not stated, one value for those states is estimated
    (:func:`estimate_shape_uncertainty`) at the first evaluation that has shape rows (the baseline at
    its start values) and then held fixed; :attr:`source` says which.
    """

    def __init__(self, on: bool, data):
        self.data = data
        self.states = [k for k, d in enumerate(data) if on and d.shapes is not None and np.isfinite(d.shapes).any()]
        self.eps = {k: getattr(data[k], "shape_sigma_rel", None) for k in self.states}
        self.source = "stated in conditions.yaml (shape_uncertainty_pct)"

    @property
    def active(self) -> bool:
        """Whether any state has shape rows."""
        return bool(self.states)

    def disable(self) -> None:
        """No shape rows (for a caller whose records count frequency rows only)."""
        self.states, self.eps = [], {}

    def _resolve(self, sols, index) -> None:
        todo = [k for k in self.states if self.eps[k] is None]
        if not todo:
            return
        est = estimate_shape_uncertainty([self.data[k] for k in todo], [sols[k] for k in todo],
                                         [np.asarray(index[k], int) for k in todo])
        for k in todo:
            self.eps[k] = max(est, MIN_SHAPE_UNCERTAINTY)
        self.source = ("estimated from the data (the misfit of the baseline's shapes at its start values, "
                       "an upper bound of the noise)")

    def block(self, solver, sols, index, directions: list) -> ShapeBlock:
        """:func:`shape_block` of the active states (uncertainties resolved first)."""
        self._resolve(sols, index)
        return shape_block(solver, self.data, sols, index, directions, self.eps)

    def extend(self, ev, solver, directions: list):
        """``ev`` with the shape rows appended after its frequency rows (``ev`` itself when inactive);
        ``directions`` per state: the coefficient derivatives of the Jacobian's columns."""
        if not self.active:
            return ev
        blk = self.block(solver, ev.solutions, ev.index, directions)
        rs, Js = blk.arrays()
        eps = np.array([self.eps[si] for si, _ in blk.rows], float)
        sigma = None if ev.sigma is None else np.concatenate([ev.sigma, eps])
        ks = blk.known_errors()
        if ev.known is None and not ks.any():
            known = None
        else:
            known = np.concatenate([np.zeros(len(ev.r)) if ev.known is None else ev.known, ks])
        return replace(ev, r=np.concatenate([ev.r, rs]), J=np.vstack([ev.J, Js]), rows=list(ev.rows) + blk.rows,
                       n_scales=blk.n_scales, sigma=sigma, known=known)

    def note(self) -> list[str]:
        """One sentence for the notes of the diagnosis: the shape rows and their uncertainty (empty when
        there are none)."""
        if not self.active or any(v is None for v in self.eps.values()):
            return []
        vals = sorted({round(100 * v, 4) for v in self.eps.values()})
        names = ", ".join(self.data[k].name for k in self.states)
        return [f"mode shapes in the fit ({names}): modal-displacement residuals after best scaling, shape "
                f"uncertainty {' / '.join(f'{v:g}' for v in vals)} % of each mode's RMS, {self.source}"]
