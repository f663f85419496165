"""The certificate of a reported optimum's modes, as a record for its JSON.

A :class:`Certificate` says how the modes were obtained (``method``: the reduced solver's Ritz pairs,
or a full shift-invert Lanczos solve), how far they are from the full model's (the largest relative
residual measure and its tolerance), whether a Sturm count confirms that no mode is missing below a
shift, and why a full solve answered when a check failed (``fallback``).

* :func:`reduced_certificate` - the residual check of the reduced solver's modes at a point (the
  identification's polish, ``params.json``: ``fe_polish.certificate``);
* :func:`full_certificate` - the residual and Sturm count of a full solve
  (:func:`jointid.fe.modal.solve_model` with ``certify=True``; rule ``verify``,
  ``certificate.json``).

The record holds no time or host, so a run gives byte-identical files.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

from jointid.fe import certify
from jointid.fe.blocklanczos import RESIDUAL_TOL

if TYPE_CHECKING:
    from jointid.fe.modal import Modes
    from jointid.fe.reduced import ReducedSolver

REDUCED_MEASURE = "estimated relative eigenvalue error |r^T (K - sigma M)^-1 r| / lambda, r = K x - lambda M x"
FULL_MEASURE = "relative residual |K x - lambda M x| / max(|K x|, |lambda| |M x|)"


@dataclass(frozen=True)
class Certificate:
    """How far a solve's lowest ``n_modes`` modes are from the full model's, and their completeness.

    ``method``: ``"reduced"`` (Ritz pairs checked in the full space) or ``"full"`` (a full solve
    answered, first or as the ``fallback``, whose text says why).  ``max_relative_residual``: the
    largest value of ``residual_measure`` over the modes, accepted up to ``residual_tol`` (None: not
    checked).  ``sturm_count``: the full model's modes below ``sturm_shift_Hz`` (None: no count), of
    which the solve found ``n_modes_below_shift``.
    """

    method: str
    n_modes: int
    max_relative_residual: float | None
    residual_measure: str
    residual_tol: float
    sturm_shift_Hz: float | None = None
    sturm_count: int | None = None
    n_modes_below_shift: int | None = None
    fallback: str | None = None

    @property
    def complete(self) -> bool | None:
        """The Sturm count equals the modes found below its shift (None: no count)."""
        if self.sturm_count is None or self.n_modes_below_shift is None:
            return None
        return self.sturm_count == self.n_modes_below_shift

    @property
    def passed(self) -> bool:
        """The residual is within its tolerance and no count says a mode is missing."""
        r = self.max_relative_residual
        return r is not None and r <= self.residual_tol and self.complete is not False

    def to_record(self) -> dict:
        """A JSON-safe dict (SI units in the key names; ``complete`` and ``passed`` included).  The
        residual keeps three significant digits: it is an error estimate, its further digits rounding noise."""
        rec = asdict(self)
        r = _finite(self.max_relative_residual)
        rec["max_relative_residual"] = None if r is None else float(f"{r:.3g}")
        return {**rec, "complete": self.complete, "passed": self.passed}

    @classmethod
    def from_record(cls, rec: dict) -> Certificate:
        """The certificate of a record of :meth:`to_record` (the derived fields are recomputed)."""
        return cls(**{k: v for k, v in rec.items() if k not in ("complete", "passed")})

    def describe(self) -> str:
        """One line for the log."""
        res = ("residual not checked" if self.max_relative_residual is None else
               f"residual {self.max_relative_residual:.1e} (tol {self.residual_tol:.0e})")
        count = ("no Sturm count" if self.sturm_count is None else
                 f"Sturm count {self.sturm_count} modes below {self.sturm_shift_Hz:.1f} Hz, "
                 f"{self.n_modes_below_shift} found")
        why = f"; fallback: {self.fallback}" if self.fallback else ""
        return (f"certificate {'passed' if self.passed else 'FAILED'} ({self.method} solve of "
                f"{self.n_modes} modes): {res}, {count}{why}")


def _finite(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def reduced_certificate(rs: ReducedSolver, kc: dict, mc: dict, n: int) -> Certificate:
    """The residual check of the reduced solver's lowest ``n`` modes at ``(kc, mc)``.

    The error certified when the point was solved (:meth:`ReducedSolver.solve`; on a larger basis
    since, Poincaré bounds it), else a fresh check on the current basis.  Neither changes the basis.
    Where the check had failed and a full solve answered (:func:`jointid.fe.certify.full_solve`),
    ``method`` is ``"full"`` and ``fallback`` says why.
    """
    prior = rs._certified.get(rs._point(kc, mc, n))
    worst = prior[1] if prior is not None and prior[0] <= rs.basis.r else \
        certify.check_points(rs, [(kc, mc)], n)[0].worst
    why = rs.fallbacks.get(rs.point_key(kc, mc))
    return Certificate("full" if why else "reduced", int(n), _finite(worst), REDUCED_MEASURE, float(rs.tol),
                       fallback=why)


def full_certificate(modes: Modes, tol: float = RESIDUAL_TOL) -> Certificate:
    """The certificate of a full solve (:func:`jointid.fe.modal.solve_model` with ``certify=True``):
    its residual and its Sturm count; ``fallback`` names the modes a first Lanczos run missed."""
    s = modes.sturm
    why = None
    if s is not None and s.recovered:
        why = (f"Sturm count {s.count} below {s.freq_Hz:.1f} Hz, {s.count - s.recovered} found: "
               f"{s.recovered} missed mode(s) recovered by a second solve from a random start")
    return Certificate("full", int(len(modes.freqs_Hz)), _finite(modes.residual), FULL_MEASURE, float(tol),
                       sturm_shift_Hz=None if s is None else float(s.freq_Hz),
                       sturm_count=None if s is None or s.count is None else int(s.count),
                       n_modes_below_shift=None if s is None else int(s.found), fallback=why)
