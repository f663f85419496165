"""Where a refit starts and which of several starts' optima is reported (docs/effects.md, "Statistics").

* :func:`refit_starts` - the start values of a one-parameter candidate;
* :func:`sized_starts` - more starts, at the effect's typical sizes, when those all ended at the null;
* :func:`rounded_start` - a start taken from an estimate, to a few significant digits;
* :func:`chi2_tie` - how far apart two chi-squares must be to be two optima;
* :func:`best_fit` - the optimum of least chi-square over several starts, twins within the solver's
  accuracy (:func:`chi2_resolution`) taken as one.
"""

from __future__ import annotations

import math

import numpy as np

START_DIGITS = 3  # significant digits of a refit's start taken from a linearised estimate
TIE_RTOL = 1e-6  # fits from several starts within this relative chi-square are one optimum (best_fit)
EIGEN_RTOL = 1e-6  # the reduced solver's relative eigenvalue tolerance (Diagnoser's default tol): best_fit's ties


def refit_starts(spec, t_hat: float) -> list[float]:
    """Start values of a one-parameter candidate: its linearised estimate, a bracket above it
    (effects saturate, so the linearised estimate tends to be low), inside the bounds, and the
    effect at (almost) its null: the refit of a nested model then never ends worse than the model
    it extends (a strong start can lock onto a pairing of its own)."""
    p = spec.effect.params[0]
    lo, hi = p.t_bounds
    hi = hi if math.isfinite(hi) else 1e6
    span = hi - lo
    base = float(np.clip(rounded_start(t_hat), lo + 1e-3 * span, hi))
    out = [base]
    for s in (3.0 * base, lo + 0.3 * span):
        s = float(np.clip(s, lo + 1e-3 * span, hi))
        if all(abs(s - o) > 0.05 * max(abs(o), 1e-3 * span) for o in out):
            out.append(s)
        if len(out) == 2:
            break
    near_null = p.t_near_null()
    if all(abs(near_null - o) > 0.05 * max(abs(o), 1e-3 * span) for o in out):
        out.append(near_null)
    return out


SIZED = (0.5, 1.0)  # sized_starts: the effect at half and at its nominal size (test variable t)


def at_its_null(spec, t: float) -> bool:
    """Whether a one-parameter candidate's fitted test variable ``t`` sits at the effect's null, within
    a thousandth of its nominal size (``t`` is in units of it): the refit found nothing to add."""
    p = spec.effect.params[0]
    lo, hi = p.t_bounds
    return abs(float(t) - float(np.clip(p.to_t(p.null), lo, hi))) <= 1e-3


def sized_starts(spec, tried: list[float]) -> list[float]:
    """Starts at the effect's typical sizes (:data:`SIZED` times its nominal value, ``t`` = 0.5 and 1),
    those not within 5 % of a start ``tried``; none for a compliance, whose nominal is not a typical
    size (base_support's 1e10 N/m^3 is 15-30 times softer than the coverage study's foundations, and a
    fit started there grows the reduced basis for every later fit: the coarse coverage cases with a
    small stated noise took 3-4 times as long with such starts).

    Asked for when every start of :func:`refit_starts` ended at the null.  The linearised estimate
    comes from the current optimum, where the joints may have absorbed much of the effect: its
    first-order direction then points to the null, and so do the starts built on it.  With the
    effect at a typical size the joints can move back (measured: a 1.5 kg edge mass on the coarse
    rig, frequencies only, refit from 0.0075 and 0.0225 ends at 0 kg with chi2 681; from t 0.5 and
    1 at 1.46 kg with chi2 2.7, the truth's basin)."""
    p = spec.effect.params[0]
    if p.kind == "compliance":
        return []
    lo, hi = p.t_bounds
    hi = hi if math.isfinite(hi) else 1e6
    out = []
    for t in SIZED:
        s = float(np.clip(t, lo, hi))
        if all(abs(s - o) > 0.05 * max(abs(o), 1e-3 * (hi - lo)) for o in list(tried) + out):
            out.append(s)
    return out


def chi2_resolution(f, eig_rtol: float = EIGEN_RTOL) -> float:
    """How far the chi-square of ``f`` can move with the solver's accuracy alone: each frequency is
    certified to a relative eigenvalue error ``eig_rtol``, so a frequency row moves by up to
    ``eig_rtol / (2 sigma_i)`` and the chi-square by ``sum |r_i| eig_rtol / sigma_i`` (first order)."""
    ev = getattr(f, "ev", None)
    if ev is None or ev.sigma is None:
        return 0.0
    from jointid.diagnosis.results import frequency_rows

    rows = frequency_rows(ev)
    return float(np.sum(np.abs(ev.r[rows]) * eig_rtol / np.asarray(ev.sigma, float)[rows]))


def chi2_tie(f, low: float | None = None) -> float:
    """How much lower than ``low`` (default: the chi-square of ``f``) another fit's chi-square must be to be a
    different, better optimum: the larger of :data:`TIE_RTOL` relative and what the solver's accuracy alone can
    move the chi-square of ``f`` (:func:`chi2_resolution`).  Closer, the two are one optimum reached twice."""
    low = f.chi2 if low is None else low
    return max(TIE_RTOL * abs(low), chi2_resolution(f)) + 1e-9


def best_fit(fits: list):
    """The fit of least chi-square over several starts; fits within :data:`TIE_RTOL` of it, or within
    what the solver's accuracy alone can move a chi-square (:func:`chi2_resolution`), are one optimum
    reached twice, and the first start's is taken.  Each chi-square is certified to the solver
    tolerance only, so a strict minimum would pick between such twins by round-off, and an identical
    question in another run (on another subspace) could be answered from the other twin."""
    finite = [f for f in fits if np.isfinite(f.chi2)]
    if not finite:
        return fits[0]
    low = min(f.chi2 for f in finite)
    return next(f for f in finite if f.chi2 <= low + chi2_tie(f, low))


def rounded_start(t: float) -> float:
    """A start value from an estimate, to :data:`START_DIGITS` significant digits: a start is a guess,
    and an estimate's last digits change with the subspace that computed it, so that rounded, a fit
    asked again from the same estimate is the same question (:mod:`jointid.diagnosis.memo`)."""
    return float(f"{float(t):.{START_DIGITS}g}")


