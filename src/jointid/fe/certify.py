"""Full-space checks of a reduced solver's Ritz pairs, and the refinement after a failed check.

A check takes the lowest ``n`` Ritz pairs ``(lambda, V y)`` of a point ``(kc, mc)`` of a
:class:`jointid.fe.reduced.ReducedSolver`, forms their residuals ``r = K(c) V y - lambda M(m) V y`` in
the full space and estimates each relative eigenvalue error as ``|r^T A^-1 r| / lambda`` with the
solver's factorisation ``A = K - sigma M`` (one sparse solve for all pairs).

:func:`check_points` checks several points together: the products of the base terms with the basis,
``K0 V`` and ``M0 V`` (the largest arrays), are read once for all of them, and one sparse solve takes
every residual.  Where the state count of a diagnosis is two, that is one pass over the basis and
one solve per pair of states instead of two.  :func:`refine` runs the enrichment loop of a point
that failed its check (Davidson steps, a new preconditioner at a distant point, exact modes when
progress stalls); should the check still fail after :data:`MAX_ROUNDS`, :func:`full_solve` answers
(the fallback, logged and kept in ``ReducedSolver.fallbacks``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from jointid.fe.modal import TWO_PI, count_pencil_modes_below



class ReducedSolver(Protocol):
    """What the checks and the refinement use of a reduced solver (:class:`jointid.fe.reduced.ReducedSolver`
    is the one; named here so that this module does not import it back)."""

    tol: float
    max_basis: int
    generation: int
    basis: Any  # jointid.fe.basis.GrowingBasis
    V: np.ndarray  # the basis on the free DOFs
    K_terms: dict  # the stiffness terms on the free DOFs (K0 first)
    M_terms: dict  # the mass terms on the free DOFs (M0 first)
    fac: Any  # the factorisation of K - sigma M at the last reference point
    pencil: Any  # jointid.fe.pencil.FreePencil
    backend: str
    n_checks: int
    n_refine: int
    sturm_counts: dict
    fallbacks: dict

    def _ritz(self, kc: dict, mc: dict, n: int | None = None) -> tuple: ...

    def _apply(self, coeffs: dict, Y: np.ndarray, group: str, base_product: np.ndarray | None = None) -> np.ndarray: ...

    def _append(self, W: np.ndarray) -> int: ...

    def _refactor(self, kc: dict, mc: dict) -> None: ...

    def settle(self) -> None: ...

    def before_check(self, n_points: int) -> None: ...

    def _reset(self, phi: np.ndarray) -> None: ...

    def _lanczos(self, kc: dict, mc: dict, k: int) -> tuple: ...

    def _say(self, msg: str) -> None: ...

    def kept_check(self, kc: dict, mc: dict, n: int) -> tuple[int, float] | None: ...

    def solve(self, kc: dict, mc: dict, n: int | None = None, **kw) -> Any: ...

    @staticmethod
    def point_key(kc: dict, mc: dict) -> str: ...


MAX_ROUNDS = 12
"""Most enrichment rounds of one point before the full solve answers instead (:func:`full_solve`)."""


@dataclass
class Check:
    """One point's check: Ritz pairs, residuals ``R``, ``D = A^-1 R`` and errors, on basis ``(generation, r)``."""

    lam: np.ndarray
    Y: np.ndarray
    R: np.ndarray
    D: np.ndarray
    err: np.ndarray
    basis: tuple

    @property
    def worst(self) -> float:
        return float(self.err.max())


def check_points(rs: ReducedSolver, points: list[tuple[dict, dict]], n: int) -> list[Check]:
    """Check the lowest ``n`` Ritz pairs of every point on the current basis (one pass, one solve)."""
    rs.before_check(len(points))
    ritz = [rs._ritz(kc, mc, n) for kc, mc in points]
    Ys = [Y[:, :n] for _, Y in ritz]
    base_K = _base_products(rs, Ys, "K")
    base_M = _base_products(rs, Ys, "M")
    if base_K[0] is None:
        base_K, base_M = _sparse_base_products(rs, Ys)
    R = [rs._apply(kc, Y, "K", base_K[i]) - rs._apply(mc, Y, "M", base_M[i]) * lam[None, :n]
         for i, ((kc, mc), (lam, _), Y) in enumerate(zip(points, ritz, Ys))]
    D_all = rs.fac.solve(np.hstack(R)) if len(R) > 1 else rs.fac.solve(R[0])
    out, at = [], 0
    basis = (rs.generation, rs.basis.r)
    for (lam, Y), Rk in zip(ritz, R):
        Dk = D_all[:, at: at + Rk.shape[1]]
        at += Rk.shape[1]
        err = np.abs(np.einsum("ij,ij->j", Rk, Dk)) / np.maximum(np.abs(lam[:n]), 1.0)
        out.append(Check(lam, Y, Rk, Dk, err, basis))
    return out


def _base_products(rs: ReducedSolver, Ys: list[np.ndarray], group: str) -> list[np.ndarray | None]:
    """``K0 V Y`` (or ``M0 V Y``) of every point from the cached product with the basis, as one
    product when there are several points (None per point when the product is not cached)."""
    prod = rs.basis.product(group, Ys[0] if len(Ys) == 1 else np.hstack(Ys))
    if prod is None or len(Ys) == 1:
        return [prod] * len(Ys)
    out, at = [], 0
    for Y in Ys:
        out.append(prod[:, at: at + Y.shape[1]])
        at += Y.shape[1]
    return out


def _sparse_base_products(rs: ReducedSolver, Ys: list[np.ndarray]) -> tuple[list, list]:
    """``K0 V Y`` and ``M0 V Y`` of every point by the sparse terms, ``V Y`` formed once for both (the
    products with the basis not cached, or deferred: :mod:`jointid.fe.basis`)."""
    rs.pencil.layout()  # K0 aligned with the pencil's pattern, as everywhere
    phis = [rs.V @ Y for Y in Ys]
    return [rs.K_terms["K0"] @ phi for phi in phis], [rs.M_terms["M0"] @ phi for phi in phis]


def refine(rs: ReducedSolver, kc: dict, mc: dict, n: int, first: Check | None = None):
    """Enrich the basis until the lowest ``n`` Ritz pairs at ``(kc, mc)`` pass their check.

    ``first``: this point's check on the current basis, when already done (:func:`check_points`).
    Returns ``(lam, Y, worst)``: all Ritz values and vectors on the final basis and the largest
    estimated relative eigenvalue error of the lowest ``n``.  When :data:`MAX_ROUNDS` do not suffice,
    the full solve's modes join the basis (:func:`full_solve`) and the Ritz values are theirs.
    """
    rs.n_checks += 1
    last = np.inf
    refactored, slow_after = False, 0
    chk = first if first is not None and first.basis == (rs.generation, rs.basis.r) else None
    for _ in range(MAX_ROUNDS):
        chk = chk or check_points(rs, [(kc, mc)], n)[0]
        lam, Y, R, D, err, worst = chk.lam, chk.Y, chk.R, chk.D, chk.err, chk.worst
        if worst <= rs.tol:
            break
        rs.n_refine += 1
        slow = worst > 0.5 * last
        slow_after += int(refactored and slow)
        if rs.basis.r > rs.max_basis:
            rs._refactor(kc, mc)
            rs._reset(rs._lanczos(kc, mc, n + 4)[0])
        elif (worst > 1e-2 or slow) and not refactored:
            # far from the reference or slow progress: this point becomes the preconditioner
            # (Davidson steps with the exact shifted inverse here)
            rs._refactor(kc, mc)
            refactored = True
            D = rs.fac.solve(R)
            rs._append(D[:, err > rs.tol])
        elif slow_after >= 2:
            # still slow with the local preconditioner: exact modes at this point
            rs._append(rs._lanczos(kc, mc, n + 4)[0])
            slow_after = -100
        else:
            rs._append(D[:, err > rs.tol])
        last = worst
        chk = None
    else:  # the check still fails: the full solve answers (its modes join the basis)
        full_solve(rs, kc, mc, n, f"residual check failed after {MAX_ROUNDS} enrichment rounds (estimated "
                   f"relative eigenvalue error {worst:.1e} > tol {rs.tol:.0e})")
        chk = check_points(rs, [(kc, mc)], n)[0]
        lam, Y, worst = chk.lam, chk.Y, chk.worst
    return lam, Y, worst


def full_solve(rs: ReducedSolver, kc: dict, mc: dict, n: int, why: str) -> np.ndarray:
    """The fallback of a failed certificate: a full Lanczos solve at ``(kc, mc)`` (factorised there),
    whose modes join the basis, so that the Ritz values there are the full solve's.  The reason is
    logged and kept in ``rs.fallbacks`` (by :meth:`ReducedSolver.point_key`).  Returns the lowest
    ``n`` full-solve frequencies (Hz)."""
    rs._say(f"certificate failed ({why}): full Lanczos solve")
    rs.fallbacks[rs.point_key(kc, mc)] = why
    rs._refactor(kc, mc)
    phi, f_full = rs._lanczos(kc, mc, n + 2)
    rs._append(phi)
    return f_full[:n]


def verify(rs: ReducedSolver, kc: dict, mc: dict, n: int) -> float:
    """Check the reduced solution at ``(kc, mc)`` against the full model.

    The lowest ``n`` Ritz pairs are checked afresh in the full space (residual test), unless an earlier
    run passed that check at this very point on the kept basis columns (:meth:`ReducedSolver.kept_check`:
    the same evidence; a Ritz value on a basis containing them lies between the checked one and the
    exact eigenvalue); a Sturm count
    between the ``n``-th and the next Ritz value (:func:`jointid.fe.modal.count_pencil_modes_below`,
    one factorisation) then confirms that they are the lowest ``n`` modes, and their estimated error
    is returned.  Where the count differs (a mode the subspace lacks), a full Lanczos solve, whose
    modes join the subspace.  Returns the largest relative frequency error over the lowest ``n``
    modes (estimated, or the difference to the full solve).
    """
    kept = rs.kept_check(kc, mc, n)
    red = rs.solve(kc, mc, n, refine=True, recheck=kept is None)
    checked = "" if kept is None else ", checked on the kept basis by an earlier run"
    lam = rs._ritz(kc, mc, n + 1)[0]
    f = np.sqrt(np.clip(lam, 0.0, None)) / TWO_PI
    count = None
    if len(f) > n and f[n] > f[n - 1] * (1.0 + 1e-6) and np.isfinite(red.error):
        at, count, earlier = _sturm_count(rs, kc, mc, f, n)
        if count == n:
            rs._say(f"certificate: residual error {red.error:.1e} (tol {rs.tol:.0e}{checked}) and Sturm count "
                    f"{count} modes below {at:.1f} Hz = the {n} Ritz values{earlier}")
            return 0.5 * red.error  # relative frequency error = half the eigenvalue error
    why = (f"Sturm count {count} for {n} Ritz values" if count is not None
           else "no gap above the last Ritz value, or the residual check did not converge")
    f_full = full_solve(rs, kc, mc, n, why)
    return float(np.max(np.abs(red.freqs_Hz - f_full) / np.maximum(f_full, 1.0)))


def _sturm_count(rs: ReducedSolver, kc: dict, mc: dict, f: np.ndarray, n: int) -> tuple[float, int | None, str]:
    """Number of modes of the full model at ``(kc, mc)`` below a frequency between the ``n``-th and
    the next Ritz value ``f`` (Hz): ``(frequency, count, note)``.

    A count is a property of the model and the point alone, so one made earlier at the same
    coefficients (this run, or a run kept with the subspace: :attr:`ReducedSolver.sturm_counts`)
    answers again wherever its frequency still lies between the two Ritz values, which only fall
    towards the exact eigenvalues as the basis grows; the note then says so.
    """
    key = rs.point_key(kc, mc)
    for at, count in rs.sturm_counts.get(key, []):
        if f[n - 1] * (1.0 + 1e-6) < at < f[n] and count == n:
            return at, count, " (counted before at this point)"
    at = 0.5 * (f[n - 1] + f[n])
    rs.settle()  # a factorisation under way records the pencil's ordering first
    count = count_pencil_modes_below(rs.pencil, kc, mc, at, rs.backend)
    if count is not None:
        rs.sturm_counts.setdefault(key, []).append((float(at), int(count)))
    return at, count, ""
