"""The next measurement with shapes: where an accelerometer pair would separate tied candidates
(issue 40, item 4; docs/effects.md, "When the data cannot decide").

For a state measured without shapes, a shape measured at two DOFs (a roving accelerometer and a
reference, or one triaxial pair of axes) adds, per measured mode, one degree of freedom to the fit: the
ratio of the two modal displacements (:mod:`jointid.diagnosis.shape_residuals`, two rows less one
best scale).  If candidate A were true and B fitted, the expected chi-square of B's shape at DOFs
``(i, j)`` is, at a noise of ``eps`` of the pair's RMS per DOF (``shape_uncertainty_pct`` as
docs/measurement-format.md defines it),

    chi2_ij = 2 (a_i b_j - a_j b_i)^2 / ((a_i^2 + a_j^2) (b_i^2 + b_j^2) eps^2)   (= 2 (1 - MAC) / eps^2),

summed over the state's paired modes that move the pair (RMS there at least :data:`VISIBLE_RMS` of the
mode's RMS over all measuring DOFs: near a node a pair measures noise, not the ratio); the proposal is
the pair with the largest smallest (over ordered candidate pairs) sum.
"""

from __future__ import annotations

import itertools

import numpy as np

from jointid.correlate.pairing import pair_by_shapes

__all__ = ["ASSUMED_SHAPE_PCT", "accelerometer_rows", "pair_chi2", "pair_text"]

VISIBLE_RMS = 0.5
"""A mode counts at a DOF pair where its RMS over the pair is at least this fraction of its RMS over all
measuring DOFs (elsewhere the pair sits near a node of it and measures noise)."""

ASSUMED_SHAPE_PCT = 5.0
"""Shape noise assumed for a proposed accelerometer measurement (1 sigma per DOF, % of the mode's RMS
over the measuring DOFs) where the dataset states none: a careful hammer test."""


def _unit_rms(phi: np.ndarray) -> np.ndarray:
    rms = np.sqrt(np.mean(phi ** 2, axis=0))
    return phi / np.where(rms > 0, rms, 1.0)


def pair_chi2(a: np.ndarray, b: np.ndarray, eps: float) -> np.ndarray:
    """``(n_dofs, n_dofs)`` expected chi-square of shapes ``b`` (model fitted) against ``a`` (truth) at each
    DOF pair, summed over the columns (modes) of ``a`` and ``b`` (unit RMS each)."""
    out = np.zeros((a.shape[0], a.shape[0]))
    for k in range(a.shape[1]):
        x, y = a[:, k], b[:, k]
        c = np.outer(x, y)
        cross = c - c.T  # a_i b_j - a_j b_i
        na = (x ** 2)[:, None] + (x ** 2)[None, :]
        den = na * ((y ** 2)[:, None] + (y ** 2)[None, :])
        seen = na >= 2 * VISIBLE_RMS ** 2  # the mode moves the pair: its RMS there >= VISIBLE_RMS of the mode's
        out += np.where(seen & (den > 0), 2.0 * cross ** 2 / np.where(den > 0, den, 1.0), 0.0)
    return out / eps ** 2


def _paired_shapes(fits: dict, names: list[str], si: int) -> list[np.ndarray]:
    """Per candidate, its probe shapes (unit RMS) of the modes paired with the measured ones in state
    ``si``, columns aligned across candidates (modes paired in every candidate only)."""
    base = fits[names[0]].ev
    idx = np.asarray(base.index[si])
    cols = [idx[idx >= 0]]
    for n in names[1:]:
        m = pair_by_shapes(base.solutions[si].shapes, fits[n].ev.solutions[si].shapes, threshold=0.5)[0]
        cols.append(m[cols[0]])
    keep = np.all([c >= 0 for c in cols], axis=0)
    return [_unit_rms(np.asarray(fits[n].ev.solutions[si].shapes, float)[:, c[keep]]) for n, c in zip(names, cols)]


def accelerometer_rows(diag, fits: dict, names: list[str], shape_pct: float = ASSUMED_SHAPE_PCT) -> list[dict]:
    """Rows of :func:`jointid.diagnosis.ambiguity.next_measurements` (kind ``shape``): for each state
    measured without shapes, the DOF pair whose shapes would best separate the candidates ``names``."""
    eps = shape_pct / 100.0
    labels = list(diag.system.labels)
    rows = []
    for si, d in enumerate(diag.data):
        if d.shapes is not None and np.isfinite(d.shapes).any():
            continue
        shapes = _paired_shapes(fits, names, si)
        if not shapes[0].shape[1]:
            continue
        score = np.min([pair_chi2(shapes[a], shapes[b], eps)
                        for a, b in itertools.permutations(range(len(names)), 2)], axis=0)
        np.fill_diagonal(score, 0.0)
        i, j = np.unravel_index(int(np.argmax(score)), score.shape)
        ref = max((i, j), key=lambda k: float(np.min(np.abs(shapes[0][k]))))  # the one every mode moves most
        lead = j if ref == i else i
        rows.append({"measurement": f"{d.name}: an accelerometer at {labels[lead]} with a reference at "
                                    f"{labels[ref]} (the shapes of the {shapes[0].shape[1]} measured modes, "
                                    f"at a shape noise of {shape_pct:g} % of each mode's RMS)",
                     "kind": "shape", "state": d.name, "em_force_N": d.info.em_force_N,
                     "expected_delta_chi2": float(score[i, j]), "points": [labels[lead], labels[ref]],
                     "predictions": "; ".join(f"{n} {labels[lead]} {labels[ref]} {pair_text(s[lead], s[ref])}"
                                              for n, s in zip(names, shapes))})
    return rows


def pair_text(lead: np.ndarray, ref: np.ndarray) -> str:
    """Per mode, the displacements at the two DOFs of a pair, each in units of the mode's RMS over all
    measuring DOFs (the shapes' normalisation here): ``[+1.83 +0.02, ...]``.  Not their ratio: where one DOF
    sits near a node of a mode the ratio runs to thousands and says nothing a reader can check."""
    return "[" + ", ".join(f"{a:+.2f} {b:+.2f}" for a, b in zip(np.asarray(lead, float), np.asarray(ref, float))) + "]"
