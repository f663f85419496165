"""Rayleigh-Ritz eigen-solver on an adaptively enriched subspace of an affine FE model.

``K(c) = K0 + sum c_a K_a``, ``M(m) = M0 + sum m_b M_b`` (a :class:`jointid.fe.affine.AffineModel`: the
FE model or the diagnosis's model with its effect terms).  The subspace starts from the exact modes at a
reference point plus their first-order responses ``A^-1 (dK - lambda dM) phi`` to given coefficient
directions.  At each refined point the residuals ``K phi - lambda M phi`` of the Ritz pairs are
checked in the full space; where the estimated relative eigenvalue error exceeds ``tol`` (1e-6 by
default) the preconditioned residuals join the subspace (Davidson steps, the preconditioner
re-factorised at a distant point; :mod:`jointid.fe.certify`).  :meth:`ReducedSolver.verify` adds a
Sturm count.  Used by the diagnosis, the hypotheses and the identification's FE polish.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from jointid.errors import ModelError
from jointid.fe import certify
from jointid.fe.basis import PRODUCT_DTYPE, GrowingBasis, stored_product
from jointid.fe.certify import Check
from jointid.fe.modal import TWO_PI, factorize_pencil, shift_invert_lanczos
from jointid.fe.pencil import FreePencil

if TYPE_CHECKING:
    from jointid.fe.affine import AffineModel


@dataclass
class Solution:
    """Eigen-solution of one state: ``freqs_Hz (n,)``, reduced vectors ``Y (r, n)``, all pairs."""

    freqs_Hz: np.ndarray
    lam: np.ndarray
    Y: np.ndarray
    lam_all: np.ndarray
    Y_all: np.ndarray
    kc: dict
    mc: dict
    shapes: np.ndarray  # (n_labels, n)
    generation: int = 0
    error: float = float("nan")  # estimated relative eigenvalue error after refinement (nan: not refined)


RITZ_MEMO = 128
"""Most points whose Ritz pairs a solver keeps (:meth:`ReducedSolver._ritz`; about 50 kB each at 448 vectors)."""
CHECKS_BEFORE_PRODUCTS = 32
"""Points a solver started from a kept basis with ``defer_products`` checks before it forms the basis's products with ``K0`` and
``M0`` (:mod:`jointid.fe.basis`): each such check multiplies by the sparse terms instead, about 0.04 s
more per point on the default mesh (448 vectors; a check of two states 0.22 s against 0.14 s), where
forming the two products costs about 3.3 core-seconds, about 80 points' worth.  A rerun whose fits the kept basis answers checks a few points."""
_THREADS = ThreadPoolExecutor(max_workers=2, thread_name_prefix="jointid-reduced")


def _background(fn, *args) -> Future:
    """``fn(*args)`` in one of two background threads.  For calls that spend their time in compiled code
    without Python's lock (a sparse product with the basis, a PARDISO factorisation), so that two of them,
    or one and the caller's own work, use the machine's second core."""
    return _THREADS.submit(fn, *args)


def pad_to_basis(Y: np.ndarray, r: int) -> np.ndarray:
    """Reduced vectors of an earlier (smaller) basis expressed in the current one."""
    return Y if Y.shape[0] == r else np.vstack([Y, np.zeros((r - Y.shape[0], Y.shape[1]))])


class ReducedSolver:
    """Rayleigh-Ritz eigen-solver of an affine model on an adaptively enriched subspace.

    Parameters
    ----------
    system : jointid.fe.affine.AffineModel
        Anything with ``stiffness`` and ``mass`` term dicts (``K0``, ``M0`` first), ``fixed``, ``probe``
        and ``n_dofs``.
    kc, mc : dict
        Reference coefficients (the subspace starts from the exact modes there).
    n_modes : int
        Number of modes returned by :meth:`solve`.
    n_seed : int, optional
        Number of reference modes whose first-order responses seed the subspace (default all).
    directions : list of (dkc, dmc)
        Coefficient directions whose first-order mode responses seed the subspace.
    shift_Hz : float
        Negative spectral shift of the factorisation ``A = K - sigma M``.
    tol : float
        Largest accepted estimated relative eigenvalue error of the returned modes.
    basis : jointid.fe.warmstart.Kept, optional
        A basis to start from instead of the reference modes and their responses (kept from an
        earlier run on the same model, :mod:`jointid.fe.warmstart`).
    prefactor : bool
        With ``basis``: factorise at the reference point in a background thread while the fits begin,
        for a caller that checks a point in the full space in any case (the diagnosis certifies its
        answers).  Without it the factorisation waits until first asked for (a rerun whose fits the
        kept basis answers never makes it).  Either way it is the same factorisation, made once.
    defer_products : bool
        With ``basis``: form the basis's products with ``K0`` and ``M0`` only after
        :data:`CHECKS_BEFORE_PRODUCTS` checked points (:meth:`before_check`), for a rerun whose records
        answer most of its questions (the diagnosis's loop); else when the solver starts.
    """

    def __init__(self, system: AffineModel, kc: dict, mc: dict, n_modes: int, directions=(), *,
                 shift_Hz: float = -10.0, backend: str = "auto", tol: float = 1e-6, max_basis: int = 900,
                 n_seed: int | None = None, basis=None, prefactor: bool = False, defer_products: bool = False):
        # many parameters: the reduced solver's options (shift, backend, tolerance, basis size, seed), keyword with defaults
        self.system = system
        self.n_modes = int(n_modes)
        self.tol = tol
        self.backend = backend
        self.max_basis = max_basis
        self.sigma = -abs(TWO_PI * shift_Hz) ** 2 if shift_Hz <= 0 else (TWO_PI * shift_Hz) ** 2
        self.pencil = FreePencil(system)
        self.free = self.pencil.free
        sel, n = self.free, system.n_dofs
        self.K_terms, self.M_terms = self.pencil.K_terms, self.pencil.M_terms
        # rows touched by each (mostly very sparse) term: projections only need those rows
        self._rows = {}
        for terms in (self.K_terms, self.M_terms):
            for k, A in terms.items():
                rows = np.flatnonzero(np.diff(A.indptr) > 0)
                self._rows[k] = (rows, A[rows][:, rows].tocsr()) if len(rows) < 0.5 * A.shape[0] else None
        self.P = system.probe[:, sel].tocsr() if len(sel) < n else system.probe.tocsr()
        self.n_full_solves = self.n_refine = 0
        self.generation = 0
        self.basis = GrowingBasis(len(sel))
        self.Kr = {k: np.zeros((0, 0)) for k in self.K_terms}
        self.Mr = {k: np.zeros((0, 0)) for k in self.M_terms}
        self.M_ref = None
        self._refined: dict = {}  # refined solutions by (coefficients, basis), see solve
        self._ritz_memo: dict = {}  # Ritz pairs by (coefficients, n, basis), see _ritz
        self._certified: dict = {}  # (coefficients, n, generation) -> (basis size, error) of a passed check
        self._kept_points: set = set()  # the keys of _certified that an earlier run's checks gave (kept basis)
        self.n_checks = self.n_checks_skipped = 0
        self.sturm_counts: dict = {}  # point_key -> [(frequency Hz, full-model modes below it)]
        self.fallbacks: dict = {}  # point_key -> why a full solve answered there (certify.full_solve)
        self.log = None  # progress lines (certificates), e.g. print
        self.mc_ref = dict(mc)
        self.adopted = None  # (basis file, columns) of a kept basis taken as it is (_start_from)
        self.n_factorizations = 0
        self._pending = None  # the reference point's factorisation under way in a background thread
        self._checked_without_products = 0  # points checked while a kept basis's products are deferred
        self._defer_products = defer_products
        if basis is not None:  # factorised when first asked for (a rerun whose fits the kept basis answers never is)
            self._fac, self._fac_at, self.M_ref = None, (kc, mc), self.M(mc)
            if prefactor:
                # the pattern laid out here first: in the thread beside the fits, its numpy steps (about
                # 1.1 s on the default mesh) held Python's lock against them, and the factorisation of the
                # loop's rerun took 5.5 s instead of 3.3 s (the loop of docs/effects.md 16.2 s against 14.8 s)
                self.pencil.layout()
                self._pending = _background(factorize_pencil, self.pencil, kc, mc, self.sigma, self.backend)
            self.sturm_counts = {k: list(v) for k, v in getattr(basis, "sturm", {}).items()}
            self._start_from(basis)
            return
        self._refactor(kc, mc)
        phi, f = self._lanczos(kc, mc, self.n_modes + 4)
        lam = (TWO_PI * f) ** 2
        self._append(phi)
        lam, phi = lam[: n_seed or len(lam)], phi[:, : n_seed or len(lam)]
        blocks = []
        for dkc, dmc in directions:
            R = np.zeros_like(phi)
            for name, c in dkc.items():
                R += c * (self.K_terms[name] @ phi)
            for name, c in dmc.items():
                R -= c * (self.M_terms[name] @ phi) * lam[None, :]
            if np.abs(R).max() > 0:
                blocks.append(self.fac.solve(R))
        if blocks:
            self._append(np.hstack(blocks))

    def _start_from(self, kept):
        """Start from a kept basis (:class:`jointid.fe.warmstart.Kept`): taken as it is, with its
        reduced matrices, when it is M-orthonormal at these reference masses; else orthonormalised."""
        V, kept.V = np.asfortranarray(kept.V), None  # taken over: the basis's first growth frees it
        if kept.mc_ref != self.mc_ref or set(kept.Kr) != set(self.K_terms) or set(kept.Mr) != set(self.M_terms):
            self._append(V)
            return
        # the kept products, else formed now, or deferred until the checks are many (before_check)
        kept_prods, kept.KV, kept.MV = (kept.KV, kept.MV), None, None
        KV, MV = (p if p is not None and p.dtype == PRODUCT_DTYPE else None for p in kept_prods)
        if (KV is None or MV is None) and not self._defer_products:
            KV, MV = self._products_with(V)
        self.basis.adopt(V, KV, MV)
        self.adopted = (kept.source, V.shape[1]) if kept.source else None  # the file its first columns are (warmstart.save)
        self.Kr, self.Mr = dict(kept.Kr), dict(kept.Mr)
        self.PV = self.P @ V
        kept_checks = kept.certified_at(self.generation)
        self._certified.update(kept_checks)
        self._kept_points = set(kept_checks)
        self._regroup()

    def before_check(self, n_points: int) -> None:
        """Called by each full-space check of ``n_points`` points (:func:`jointid.fe.certify.check_points`):
        a kept basis's deferred products ``K0 V`` and ``M0 V`` are formed once
        :data:`CHECKS_BEFORE_PRODUCTS` points have been checked without them (``K0 V`` in a background
        thread beside ``M0 V``).  The count, not the clock, decides: the same run forms them at the same check."""
        if not self.basis.deferred:
            return
        self._checked_without_products += n_points
        if self._checked_without_products > CHECKS_BEFORE_PRODUCTS:
            self.basis.form_products(*self._products_with(self.V))
            self._say(f"the products of the {self.V.shape[1]} kept vectors with K0 and M0 formed after "
                      f"{self._checked_without_products - n_points} points checked without them")

    def _products_with(self, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``K0 V`` and ``M0 V`` as the basis stores them: ``K0 V`` in a background thread beside ``M0 V``."""
        self.pencil.layout()  # K0 aligned with the pencil's pattern (made by a factorisation under way, or here)
        KV = _background(stored_product, self.K_terms["K0"], V)
        MV = stored_product(self.M_terms["M0"], V)  # here, beside K0's
        return KV.result(), MV

    @property
    def V(self) -> np.ndarray:
        """The M_ref-orthonormal basis on the free DOFs, ``(n_free, r)``."""
        return self.basis.V

    # ------------------------------------------------------------ assembly helpers
    def K(self, kc: dict) -> sp.csr_matrix:
        """Full stiffness matrix (free DOFs) at coefficients ``kc``."""
        return self.pencil.K(kc)

    def M(self, mc: dict) -> sp.csr_matrix:
        """Full mass matrix (free DOFs) at coefficients ``mc``."""
        return self.pencil.M(mc)

    @property
    def fac(self):
        """The factorisation of ``K - sigma M`` at the last point factorised (made again there after
        :meth:`release_factor`)."""
        if self._fac is None:
            if self._pending is not None:
                self._take_pending()
            else:
                self._refactor(*self._fac_at)
        return self._fac

    def settle(self) -> None:
        """Wait for the background factorisation (``prefactor``) to finish and keep it: before any other
        factorisation of the pencil, whose fill-reducing ordering the first one records."""
        if self._pending is not None:
            self._take_pending()

    def _take_pending(self) -> None:
        pending, self._pending = self._pending, None
        self.n_factorizations += 1
        self._fac = self._factor_or_error(pending.result)

    def release_factor(self) -> None:
        """Free the factorisation while other work in the process needs the memory (the edge levels)."""
        self.settle()
        if getattr(self, "_fac", None) is not None:
            self._fac.free()
            self._fac = None

    def _refactor(self, kc, mc):
        self.release_factor()
        self.n_factorizations += 1
        self._fac_at = (kc, mc)
        self._fac = self._factor_or_error(lambda: factorize_pencil(self.pencil, kc, mc, self.sigma, self.backend))
        if self.M_ref is None:
            self.M_ref = self.M(mc)

    @staticmethod
    def _factor_or_error(make):
        try:
            return make()
        except ModelError as exc:
            detail = getattr(exc, "detail", exc)
            raise ModelError(f"diagnosis: factorisation of K - sigma M failed ({detail}) — a stiffness "
                             "coefficient is zero or negative; check the joint parameters and effects") from None

    def _lanczos(self, kc, mc, k):
        """Exact modes at ``(kc, mc)`` with the current factorisation: mass-normalised vectors, Hz."""
        self.n_full_solves += 1
        return shift_invert_lanczos(self.K(kc), self.M(mc), self.fac, k, self.sigma)

    def _append(self, W: np.ndarray) -> int:
        """M_ref-orthonormalise ``W`` against the basis, drop dependent columns, project the terms."""
        self.pencil.layout()
        M = self.M_ref
        W = np.ascontiguousarray(W, dtype=float)  # C order (see below); the caller's array is not changed
        norms0 = np.sqrt(np.einsum("ij,ij->j", W, M @ W))
        # C order: a column selection leaves W in Fortran order, and every sparse product would copy it
        W = np.ascontiguousarray(W[:, norms0 > 0] / norms0[norms0 > 0])
        for _ in range(2):
            if self.V.shape[1]:
                W -= self.V @ (self.V.T @ (M @ W))
        G = W.T @ (M @ W)
        G = 0.5 * (G + G.T)
        w, Q = np.linalg.eigh(G)
        keep = w > 1e-10
        if not keep.any():
            return 0
        W = W @ (Q[:, keep] / np.sqrt(w[keep]))
        # one more pass for numerical orthogonality
        if self.V.shape[1]:
            W -= self.V @ (self.V.T @ (M @ W))
        G = W.T @ (M @ W)
        Lc = np.linalg.cholesky(0.5 * (G + G.T))
        W = sla.solve_triangular(Lc, W.T, lower=True).T
        V_old = self.V
        keep = self.basis.keep_products
        base_products = {}
        for group, terms, red in (("K", self.K_terms, self.Kr), ("M", self.M_terms, self.Mr)):
            for name, A in terms.items():
                sub = self._rows[name]
                if sub is None:
                    AW = A @ W
                    off = V_old.T @ AW
                    blk = W.T @ AW
                    if keep and name in ("K0", "M0"):
                        base_products[name] = AW
                else:
                    rows, Ars = sub
                    AW = Ars @ W[rows]
                    off = V_old[rows].T @ AW
                    blk = W[rows].T @ AW
                old = red[name]
                red[name] = np.block([[old, off], [off.T, 0.5 * (blk + blk.T)]])
        # the probe rows of the basis, extended by the new columns alone (the basis is stored in
        # Fortran order, which a sparse product with all of it would copy whole at every append)
        PW = self.P @ W
        self.PV = PW if V_old.shape[1] == 0 else np.hstack([self.PV, PW])
        self.basis.append(W, base_products.get("K0"), base_products.get("M0"))
        self._regroup()
        return W.shape[1]

    def _regroup(self):
        self._group_red, self._group_size = {}, {}
        for name, A in self.Kr.items():
            if "@" in name:
                g = name.split("@")[0]
                self._group_red[g] = self._group_red.get(g, 0.0) + A
                self._group_size[g] = self._group_size.get(g, 0) + 1

    def _grouped(self, coeffs: dict, red: dict, base: str):
        """Sum ``base + sum c_a red[a]``, using the pre-summed carriage groups where all carriages of a
        joint layer share one coefficient (the usual case)."""
        out = red[base].copy()
        groups: dict[str, list] = {}
        for name, c in coeffs.items():
            if c == 0.0:
                continue
            if "@" in name:
                groups.setdefault(name.split("@")[0], []).append((name, c))
            else:
                out += c * red[name]
        for g, items in groups.items():
            cs = [c for _, c in items]
            if len(items) == self._group_size.get(g, -1) and max(cs) == min(cs):
                out += cs[0] * self._group_red[g]
            else:
                for name, c in items:
                    out += c * red[name]
        return out

    # ------------------------------------------------------------ solve
    def _ritz(self, kc, mc, n=None):
        """The lowest ``n`` Ritz pairs at ``(kc, mc)`` on the current basis; a point asked again on the
        same basis (a fit's optimum evaluated, then certified, then described) is answered from
        :attr:`_ritz_memo` (copies: the same bits, no second dense eigen-solve)."""
        key = self._key(kc, mc, n or self.n_modes)
        hit = self._ritz_memo.get(key)
        if hit is None:
            Kr, Mr = self._grouped(kc, self.Kr, "K0"), self._grouped(mc, self.Mr, "M0")
            m = min(n or self.n_modes, Kr.shape[0])
            hit = sla.eigh(Kr, Mr, check_finite=False, subset_by_index=[0, m - 1], driver="gvx")
            if len(self._ritz_memo) >= RITZ_MEMO:
                self._ritz_memo.pop(next(iter(self._ritz_memo)))
            self._ritz_memo[key] = hit
        return hit[0].copy(), hit[1].copy()

    def _apply(self, coeffs: dict, Y: np.ndarray, group: str, base_product: np.ndarray | None = None) -> np.ndarray:
        """``A(coeffs) V Y`` for the stiffness (``group`` "K") or mass ("M") on the free DOFs: the
        base term from its cached product with the basis (``base_product``: that product with ``Y``,
        when already formed), every other term on the rows it touches."""
        self.pencil.layout()
        terms, base = (self.K_terms, "K0") if group == "K" else (self.M_terms, "M0")
        V = self.V
        c0 = 1.0 + coeffs.get(base, 0.0)
        phi = None
        base_product = base_product if base_product is not None else self.basis.product(group, Y)
        if base_product is not None:
            out = c0 * base_product
        else:
            phi = V @ Y
            out = c0 * (terms[base] @ phi)
        for name, c in coeffs.items():
            if name == base or c == 0.0:
                continue
            if name not in terms:
                raise KeyError(f"no {group} term named {name!r}; the model has {sorted(terms)}")
            sub = self._rows[name]
            if sub is None:
                phi = V @ Y if phi is None else phi
                out += c * (terms[name] @ phi)
            else:
                rows, Ars = sub
                out[rows] += c * (Ars @ (V[rows] @ Y))
        return out

    def _key(self, kc: dict, mc: dict, n: int) -> tuple:
        return (tuple(sorted(kc.items())), tuple(sorted(mc.items())), n, self.generation, self.basis.r)

    @staticmethod
    def point_key(kc: dict, mc: dict) -> str:
        """A text key of the coefficients ``(kc, mc)`` (exact: each value's hexadecimal float)."""
        return ";".join(f"{k}={float(v).hex()}" for k, v in sorted(kc.items())) + "|" + \
            ";".join(f"{k}={float(v).hex()}" for k, v in sorted(mc.items()))

    def _point(self, kc: dict, mc: dict, n: int) -> tuple:
        return (tuple(sorted(kc.items())), tuple(sorted(mc.items())), n, self.generation)

    def solve(self, kc: dict, mc: dict, n: int | None = None, *, refine: bool = True,
              recheck: bool = False, first: Check | None = None) -> Solution:
        """Lowest ``n`` modes at coefficients ``(kc, mc)``, refined until their estimated error < tol.

        A point whose full-space check passed on an earlier, smaller basis of the same generation is
        not checked again (unless ``recheck``): the basis has only grown since, and on a larger
        subspace every Ritz value lies between the earlier one and the exact eigenvalue (Poincaré's
        min-max), so the eigenvalue errors are at most those certified then (``Solution.error``).
        ``first``: this point's check on the current basis, when already done (:meth:`solve_many`).
        """
        n = n or self.n_modes
        if refine:
            hit = self._refined_at(kc, mc, n)
            if hit is not None:
                return hit
        prior = None if recheck or not refine else self._certified.get(self._point(kc, mc, n))
        checked = False
        if self._passed(prior):
            self.n_checks_skipped += 1
            (lam, Y), worst = self._ritz(kc, mc, n), prior[1]
        elif refine:
            lam, Y, worst = certify.refine(self, kc, mc, n, first)
            checked = True
        else:
            (lam, Y), worst = self._ritz(kc, mc, n), float("nan")
        lam_n = lam[:n]
        freqs = np.sqrt(np.clip(lam_n, 0.0, None)) / TWO_PI
        sol = Solution(freqs_Hz=freqs, lam=lam_n, Y=Y[:, :n], lam_all=lam, Y_all=Y, kc=dict(kc),
                       mc=dict(mc), shapes=self.PV @ Y[:, :n], generation=self.generation, error=worst)
        if checked and worst <= self.tol:  # checked on this very basis
            if len(self._refined) > 64:
                self._refined.clear()
            self._refined[self._key(kc, mc, n)] = sol
            self._certify(kc, mc, n, self.basis.r, worst)
        return sol

    def kept_check(self, kc: dict, mc: dict, n: int) -> tuple[int, float] | None:
        """``(basis size, estimated error)`` of the check an earlier run passed at this very point on
        the kept columns (:mod:`jointid.fe.warmstart`), while the basis still contains them; else None."""
        key = self._point(kc, mc, n)
        hit = self._certified.get(key) if key in self._kept_points else None
        return hit if self._passed(hit) else None

    def _refined_at(self, kc: dict, mc: dict, n: int) -> Solution | None:
        """The solution refined at this point on this very basis, to the present tolerance (:meth:`tighten`); else None."""
        hit = self._refined.get(self._key(kc, mc, n))
        return hit if hit is not None and hit.error <= self.tol else None

    def _passed(self, check: tuple[int, float] | None) -> bool:
        """Whether a check ``(basis size, estimated error)`` passed at this point still holds: on a basis no larger
        than the present one (of this generation) and within the present tolerance (:meth:`tighten`)."""
        return check is not None and check[0] <= self.basis.r and check[1] <= self.tol

    def tighten(self, tol: float) -> None:
        """Lower the tolerance to ``tol``: a point checked only to the looser one is checked again when next solved."""
        self.tol = min(self.tol, float(tol))

    def _certify(self, kc: dict, mc: dict, n: int, r: int, worst: float) -> None:
        if len(self._certified) > 4096:
            self._certified.clear()
        key = self._point(kc, mc, n)
        if not self._passed(self._certified.get(key)):  # the first check that passed at the present tolerance
            self._certified[key] = (r, worst)

    def solve_many(self, points: list[tuple[dict, dict]], n: int | None = None, *,
                   refine: bool = True) -> list[Solution]:
        """:meth:`solve` at several points (e.g. the states of one parameter vector); the points not
        yet certified are first checked together (:func:`jointid.fe.certify.check_points`)."""
        n = n or self.n_modes
        todo = [(kc, mc) for kc, mc in points if refine and self._refined_at(kc, mc, n) is None
                and not self._passed(self._certified.get(self._point(kc, mc, n)))]
        firsts = {}
        if len(todo) > 1:
            for (kc, mc), chk in zip(todo, certify.check_points(self, todo, n)):
                if chk.worst <= self.tol:  # certified on this basis, whatever the others add to it
                    self.n_checks += 1
                    self._certify(kc, mc, n, chk.basis[1], chk.worst)
                else:
                    firsts[self._point(kc, mc, n)] = chk
        return [self.solve(kc, mc, n, refine=refine, first=firsts.get(self._point(kc, mc, n)))
                for kc, mc in points]

    def _reset(self, phi):
        self.generation += 1
        self.basis = GrowingBasis(phi.shape[0])
        self.Kr = {k: np.zeros((0, 0)) for k in self.K_terms}
        self.Mr = {k: np.zeros((0, 0)) for k in self.M_terms}
        self._append(phi)

    def _say(self, msg: str):
        if self.log is not None:
            self.log("reduced solver: " + msg)

    def full_phi(self, sol: Solution) -> np.ndarray:
        """Mass-normalised full-space mode shapes of a solution, ``(n_dofs, n)`` (zeros at fixed DOFs)."""
        phi = np.zeros((self.system.n_dofs, sol.Y.shape[1]))
        phi[self.free] = self.V @ sol.Y
        return phi

    def verify(self, kc: dict, mc: dict, n: int | None = None) -> float:
        """The certificate of the point ``(kc, mc)``: :func:`jointid.fe.certify.verify`."""
        return certify.verify(self, kc, mc, n or self.n_modes)

    def sensitivity(self, sol: Solution, dkc: dict, dmc: dict) -> np.ndarray:
        """``dlambda / dx`` of the ``n`` modes of ``sol`` for one coefficient direction, ``(n,)``."""
        return self.sensitivities(sol, [(dkc, dmc)])[0]

    def sensitivities(self, sol: Solution, directions) -> list[np.ndarray]:
        """:meth:`sensitivity` for each ``(dkc, dmc)`` of ``directions``; each term's ``diag(Y^T A_t Y)`` is
        formed once for all of them (the directions of a fit share terms: a joint layer's stiffness and an
        effect that scales it), and summed as :meth:`sensitivity` sums it (the same bits)."""
        Y = pad_to_basis(sol.Y, self.V.shape[1])
        energy: dict = {}

        def term(group: str, name: str) -> np.ndarray:
            if (group, name) not in energy:
                red = self.Kr if group == "K" else self.Mr
                energy[group, name] = np.einsum("ij,ij->j", Y, red[name] @ Y)
            return energy[group, name]

        out = []
        for dkc, dmc in directions:
            d = np.zeros(Y.shape[1])
            for name, c in dkc.items():
                if c != 0.0:
                    d += c * term("K", name)
            for name, c in dmc.items():
                if c != 0.0:
                    d -= c * sol.lam * term("M", name)
            out.append(d)
        return out
