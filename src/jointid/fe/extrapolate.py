"""Mesh extrapolation of modal frequencies over nested edge-refinement levels.

The lateral modes of the rig converge slowly under mesh refinement because their load path runs
through bonded 90-degree re-entrant edges (rail foot, block skirts, block-to-table junction), whose
stress singularities a polynomial basis resolves only about linearly in the cell size.  Local
refinement at those edges (``mesh.edge_refine_levels``, :mod:`jointid.geometry.localrefine`) halves the cells
across the edges once per level, and each level then moves a frequency by a near-constant fraction
``r`` of what the previous level moved (measured on the rig: 0.85, 0.39, 0.19, 0.09 % for table sway,
``r`` about 0.46-0.49): a geometric sequence, whose limit Aitken's delta-squared process gives from
three members,

    f_lim = f2 + (f2 - f1) r / (1 - r),    r = (f2 - f1) / (f1 - f0).

With ``mesh.extrapolate_edges`` the identification fits these limits instead of the frequencies of
one mesh: the model is solved at the current optimum on the base mesh and on the meshes with one and
two more edge levels (nested, so a mode can only fall from one to the next), the modes are followed
across the meshes by MAC at the measuring points, and each mode's frequency is scaled by its factor
``f_lim / f0`` (:class:`FrequencyCorrection`), which follows the parameters to first order through
the exact modal sensitivities on each mesh.  Where the sequence is not geometric (``r`` outside
``(0, max_ratio]``) the finest mesh's frequency is used and the mode is flagged; where it no longer
moves (relative change below ``converged_rel``) it is taken as converged.

With a given ratio (``mesh.edge_ratio``) one more level is solved instead of two, and every mode takes
that ratio: ``f_lim = f1 + (f1 - f0) r / (1 - r)`` (:func:`geometric_limit`).  On the rig the ratios
lie between 0.39 and 0.49, so a ratio of 0.45 puts the limits within about 0.1 % of Aitken's
(docs/reconstruction.md, "Mesh extrapolation"), for one large solve less per state.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from jointid.correlate.pairing import pair_by_shapes

N_LEVELS = 2  # meshes beyond the base: Aitken needs three members of the sequence
CONVERGED_REL = 1e-6  # a mode moving less than this (relative) between the finest two meshes is converged
MAX_RATIO = 0.8  # larger contraction ratios are not (yet) in the asymptotic range
MAC_FOLLOW = 0.8  # a mode is the same mode on another mesh / at another iterate above this MAC


def aitken(f0, f1, f2, *, converged_rel: float = CONVERGED_REL, max_ratio: float = MAX_RATIO):
    """Aitken limit of the sequences ``f0, f1, f2`` (arrays, element-wise).

    Returns ``(limit, ratio, status)``; ``status`` per element: ``extrapolated``, ``converged`` (the
    last change is below ``converged_rel`` of the value: limit = ``f2``) or ``not asymptotic`` (the
    ratio of successive changes lies outside ``(0, max_ratio]``: limit = ``f2``, the best value at hand).
    """
    f0, f1, f2 = (np.asarray(a, float) for a in (f0, f1, f2))
    d1, d2 = f1 - f0, f2 - f1
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(d1 != 0, d2 / d1, np.nan)
    conv = np.abs(d2) <= converged_rel * np.abs(f2)
    good = ~conv & (r > 0) & (r <= max_ratio)
    rr = np.where(good, r, 0.0)
    limit = np.where(good, f2 + d2 * rr / (1 - rr), f2)
    status = np.where(conv, "converged", np.where(good, "extrapolated", "not asymptotic"))
    return limit, r, status


def geometric_limit(f0, f1, ratio: float, *, converged_rel: float = CONVERGED_REL):
    """Limit of the geometric sequences starting ``f0, f1`` (arrays) with the contraction ``ratio``:
    ``(limit, ratio per element, status)`` as :func:`aitken`.  A mode that rises from one mesh to the
    next (nested meshes lower every frequency) is ``not asymptotic``: limit ``f1``."""
    f0, f1 = np.asarray(f0, float), np.asarray(f1, float)
    d1 = f1 - f0
    conv = np.abs(d1) <= converged_rel * np.abs(f1)
    good = ~conv & (d1 < 0)
    limit = np.where(good, f1 + d1 * ratio / (1 - ratio), f1)
    status = np.where(conv, "converged", np.where(good, "extrapolated", "not asymptotic"))
    return limit, np.full(f0.shape, float(ratio)), status


def aitken_weights(ratio, status, n_levels: int = 3) -> np.ndarray:
    """``d f_lim / d (f0, f1, f2)`` of :func:`aitken`, per mode ``(n, 3)``; with ``n_levels`` 2
    ``d f_lim / d (f0, f1)`` of :func:`geometric_limit` (the ratio given).

    For an extrapolated mode ``(r^2, -2 r, 1) / (1 - r)^2``; where the finest value is used
    ``(0, 0, 1)``; for a mode kept at its base value (``lost``) ``(1, 0, 0)``.  Each row sums to 1.
    """
    r = np.nan_to_num(np.asarray(ratio, float))
    status = np.asarray(status)
    if n_levels == 2:  # the ratio given: (-r, 1) / (1 - r)
        w = np.stack([-r, np.ones_like(r)], axis=1) / (1 - r)[:, None]
        w[status != "extrapolated"] = (0.0, 1.0)
        w[status == "lost"] = (1.0, 0.0)
        return w
    with np.errstate(divide="ignore", invalid="ignore"):  # r = 1 is never extrapolated; its row is replaced
        w = np.stack([r**2, -2 * r, np.ones_like(r)], axis=1) / ((1 - r) ** 2)[:, None]
    w[status != "extrapolated"] = (0.0, 0.0, 1.0)
    w[status == "lost"] = (1.0, 0.0, 0.0)
    return w


def follow(shapes_a: np.ndarray, shapes_b: np.ndarray, threshold: float = MAC_FOLLOW) -> np.ndarray:
    """Mode of set b continuing each mode of set a (MAC at the measuring points, one-to-one; -1: none)."""
    return pair_by_shapes(shapes_a, shapes_b, threshold)[0]


@dataclass
class EdgeLimit:
    """Frequencies of the base mesh's modes on the edge-level sequence and their limits."""

    levels_Hz: np.ndarray  # (3, n): base, +1, +2 levels, or (2, n) with a given ratio (NaN: not followed)
    limit_Hz: np.ndarray  # (n,)
    ratio: np.ndarray  # (n,)
    status: list[str]
    shapes: np.ndarray  # base-mesh shapes at the measuring points (n_labels, n)
    n_dofs: list[int] = field(default_factory=list)
    slope: np.ndarray | None = None  # d ln(f_lim / f0) / d log10 theta (n, n_params), when sensitivities were given

    @property
    def factor(self) -> np.ndarray:
        return self.limit_Hz / self.levels_Hz[0]

    def table(self):
        import pandas as pd

        return pd.DataFrame({"mode": np.arange(1, self.limit_Hz.size + 1),
                             **{f"level{k}_Hz": self.levels_Hz[k] for k in range(self.levels_Hz.shape[0])},
                             "limit_Hz": self.limit_Hz, "ratio": self.ratio, "factor": self.factor,
                             "status": self.status})


def edge_limit(solves: list, ratio: float | None = None) -> EdgeLimit:
    """Extrapolate the modes of ``solves[0]`` over the sequence ``solves`` (base, +1, +2 levels; with
    a given contraction ``ratio``: base, +1, :func:`geometric_limit`).

    Each entry is ``(freqs_Hz, shapes at the measuring points, n_dofs)`` from one mesh at the same
    joint parameters, optionally with a fourth member, ``d ln f / d log10 theta`` of its modes
    ``(n_modes, n_params)``: then the limit's factor gets its first-order dependence on the
    parameters (``slope``).  Modes are followed from each mesh to the next by MAC (the finer meshes
    should be solved for a few more modes than the base, so that the top base modes find their
    partner).  A base mode not followed to the finest mesh keeps its base frequency (``lost``).
    """
    need = 2 if ratio else N_LEVELS + 1
    if len(solves) != need:
        raise ValueError(f"edge_limit needs {need} meshes{' with a given ratio' if ratio else ''}, got {len(solves)}")
    f_base, s_base = solves[0][:2]
    n = len(f_base)
    levels = np.full((len(solves), n), np.nan)
    levels[0] = f_base
    rows = [np.arange(n)]  # each base mode's index on every mesh (-1: not followed)
    idx = np.arange(n)
    shapes_prev = s_base
    for k, (f, s, *_) in enumerate(solves[1:], start=1):
        nxt = follow(shapes_prev, s)  # shapes_prev: column i is base mode i on the previous mesh
        idx = np.where(idx >= 0, nxt, -1)
        rows.append(idx)
        levels[k] = np.where(idx >= 0, f[np.clip(idx, 0, None)], np.nan)
        shapes_prev = np.where(idx[None, :] >= 0, s[:, np.clip(idx, 0, None)], shapes_prev)
    lim, ratio, status = geometric_limit(*levels, ratio) if ratio else aitken(*levels)
    lost = np.isnan(levels).any(axis=0)
    lim = np.where(lost, f_base, lim)
    status = np.where(lost, "lost", status)
    slope = None
    if all(len(sv) > 3 and sv[3] is not None for sv in solves):
        # d f_lim / d log10 theta = sum_k w_k f_k J_k; the factor's: that / f_lim - J_0
        w = aitken_weights(ratio, status, len(solves))
        dlim = np.zeros((n, np.asarray(solves[0][3]).shape[1]))
        for k, (sv, r) in enumerate(zip(solves, rows)):
            J = np.asarray(sv[3])[np.clip(r, 0, None)]
            dlim += np.where((r >= 0)[:, None], (w[:, k] * np.nan_to_num(levels[k]))[:, None] * J, 0.0)
        slope = dlim / lim[:, None] - np.asarray(solves[0][3])
    return EdgeLimit(levels, lim, ratio, [str(s) for s in status], np.asarray(s_base),
                     [int(sv[2]) for sv in solves], slope)


class FrequencyCorrection:
    """Scale a mode's frequency by the factor of the reference mode it continues (MAC >= 0.8).

    Built from an :class:`EdgeLimit` at one parameter point ``theta_ref``; applied at nearby points,
    where the modes are followed by shape, so that a factor stays with its mode through veering and
    order changes.  With ``slope`` (``d ln factor / d log10 theta``) a factor follows the parameters
    to first order: ``factor * exp(slope . (log10 theta - log10 theta_ref))``.  A mode without a
    partner keeps its frequency (factor 1).
    """

    def __init__(self, ref_shapes: np.ndarray, factor: np.ndarray, slope: np.ndarray | None = None,
                 theta_ref: np.ndarray | None = None):
        self.ref_shapes = np.asarray(ref_shapes)
        self.factor = np.asarray(factor, float)
        if self.ref_shapes.shape[1] != self.factor.size:
            raise ValueError("one factor per reference shape")
        if (slope is None) != (theta_ref is None):
            raise ValueError("slope and theta_ref go together")
        self.slope = None if slope is None else np.asarray(slope, float)
        self.y_ref = None if theta_ref is None else np.log10(np.asarray(theta_ref, float))

    @classmethod
    def from_limit(cls, lim: EdgeLimit, theta_ref=None) -> "FrequencyCorrection":
        return cls(lim.shapes, lim.factor, *((lim.slope, theta_ref) if lim.slope is not None else (None, None)))

    def record(self) -> dict:
        """JSON form (``ref_shapes`` at the measuring points, ``factor``, ``slope`` per log10 unit of
        each parameter, ``theta_ref`` in N/m^3, in the parameters' order, which the caller records
        beside it: JSON objects do not keep an order); :meth:`from_record` reads it back."""
        return {"ref_shapes": self.ref_shapes.tolist(), "factor": self.factor.tolist(),
                "slope": None if self.slope is None else self.slope.tolist(),
                "theta_ref": None if self.y_ref is None else (10 ** self.y_ref).tolist()}

    @classmethod
    def from_record(cls, rec: dict) -> "FrequencyCorrection":
        slope, theta = rec.get("slope"), rec.get("theta_ref")
        return cls(np.asarray(rec["ref_shapes"], float), np.asarray(rec["factor"], float),
                   None if slope is None else np.asarray(slope, float), None if theta is None else np.asarray(theta))

    def factors(self, shapes: np.ndarray, theta=None) -> tuple[np.ndarray, np.ndarray | None]:
        """Factor of each mode (columns of ``shapes``) at ``theta``, and its ``d ln / d log10 theta``
        (rows; ``None`` without a slope)."""
        n = shapes.shape[1]
        out = np.ones(n)
        grad = None if self.slope is None else np.zeros((n, self.slope.shape[1]))
        dy = None if self.slope is None else np.log10(np.asarray(theta, float)) - self.y_ref
        for i, j in enumerate(follow(self.ref_shapes, shapes)):
            if j >= 0:
                out[j] = self.factor[i] * (1.0 if grad is None else np.exp(self.slope[i] @ dy))
                if grad is not None:
                    grad[j] = self.slope[i]
        return out, grad

