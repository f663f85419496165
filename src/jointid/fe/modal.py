"""Modal solutions: shift-invert Lanczos with a sparse Cholesky backend, Sturm counts (MAC: jointid.correlate).

Backends for the factorisation of ``K - sigma M`` (symmetric positive definite for sigma < 0):

* ``pardiso``: Intel MKL PARDISO through ``pypardiso``, factorised once and reused for every Lanczos
  step (a few times faster than SuperLU at 10^5 DOFs);
* ``scipy``: SuperLU (``scipy.sparse.linalg.splu``), always available;
* ``auto``: pardiso when importable, else scipy.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from jointid.errors import ModelError, NumericalWarning
from jointid.threads import import_pypardiso
from jointid.fe.backends import _PardisoFactor, _SuperLUFactor
from jointid.fe.blocklanczos import (BLOCK, MIN_DOFS, RESIDUAL_TOL, block_shift_invert, true_residual,
                                     wanted_basis)
from jointid.fe.blocklanczos import TOL as BLOCK_TOL

TWO_PI = 2.0 * np.pi


# ------------------------------------------------------------------ factorisation backends
def available_backend(name: str = "auto") -> str:
    """Resolve ``auto`` to the fastest installed backend; reject unknown names."""
    if name not in ("auto", "pardiso", "scipy"):
        raise ModelError(f"solver.backend: '{name}' is unknown — use auto, pardiso or scipy")
    if name in ("auto", "pardiso"):
        try:
            import_pypardiso()
            return "pardiso"
        except Exception:
            if name == "pardiso":
                raise ModelError("solver.backend: pardiso requested but pypardiso is not installed — "
                                 "pip install pypardiso, or set solver.backend: scipy")
    return "scipy"


def factorize(A: sp.spmatrix, backend: str = "auto", ordering: np.ndarray | None = None):
    """Factorise an SPD sparse matrix; returns an object with ``solve(b)`` and ``free()``.

    ``ordering``: a fill-reducing permutation of ``A``'s rows found before (:func:`model_ordering`);
    PARDISO then skips its reordering (used only when its length matches).
    """
    backend = available_backend(backend)
    return _PardisoFactor(A.tocsr(), ordering=ordering) if backend == "pardiso" else _SuperLUFactor(A)


def model_ordering(model, shift_Hz: float = -10.0, backend: str = "auto") -> np.ndarray | None:
    """PARDISO's nested-dissection ordering of ``K - sigma M`` on the model's free DOFs, with every
    affine term present (the pattern of any parameter point); ``None`` without PARDISO.  Cached with
    the model (``model.ordering``), it saves every later factorisation its reordering step."""
    if available_backend(backend) != "pardiso":
        return None
    ones_k = {k: 1.0 for k in model.stiffness if k != "K0"}
    ones_m = {k: 1.0 for k in model.mass if k != "M0"}
    A = restrict(model.K(ones_k) - shift_sigma(shift_Hz) * model.M(ones_m), free_dofs(model.n_dofs, model.fixed))
    return _PardisoFactor(A, analyse_only=True).ordering


def _factor_error(exc: Exception) -> ModelError:
    err = ModelError(f"solver: factorisation of K - sigma*M failed ({exc}) — the stiffness is "
                     "singular or indefinite at this shift; check the joint stiffness (zero?) and "
                     "supports, or use a negative solver.shift_Hz")
    err.detail = str(exc)  # the backend's own words, for callers that phrase their own advice
    return err


def factorize_shifted(Kf: sp.spmatrix, Mf: sp.spmatrix, sigma: float, backend: str = "auto",
                      ordering: np.ndarray | None = None):
    """Factorisation of ``K - sigma M`` (free DOFs), with a clear error when it fails."""
    backend = available_backend(backend)
    try:
        A = (Kf - sigma * Mf).tocsr()
        if backend == "pardiso":  # only the upper triangle is factorised: the whole matrix is
            A = sp.triu(A, format="csr")  # dropped before PARDISO runs (lower peak memory)
            return _PardisoFactor(A, upper=True, ordering=ordering)
        return factorize(A, backend, ordering)
    except Exception as exc:  # singular or not positive definite
        raise _factor_error(exc) from None


def factorize_pencil(pencil, kc: dict, mc: dict, sigma: float, backend: str = "auto"):
    """Factorisation of ``K(kc) - sigma M(mc)`` of a :class:`jointid.fe.pencil.FreePencil`.

    With PARDISO the upper triangle is passed as assembled and the fill-reducing ordering of the
    pencil's (fixed) pattern is computed once and reused (``pencil.ordering``).
    """
    backend = available_backend(backend)
    try:
        if backend == "pardiso":
            fac = _PardisoFactor(pencil.shifted_upper(kc, mc, sigma), upper=True, ordering=pencil.ordering)
            pencil.ordering = fac.ordering
            return fac
        return _SuperLUFactor(pencil.shifted(kc, mc, sigma))
    except Exception as exc:  # singular or not positive definite
        raise _factor_error(exc) from None


def count_modes_below(Kf: sp.spmatrix, Mf: sp.spmatrix, freq_Hz: float, backend: str = "auto",
                      ordering: np.ndarray | None = None) -> int | None:
    """Sturm count: the number of eigenvalues of ``K phi = w^2 M phi`` (free DOFs) below ``freq_Hz``.

    By Sylvester's law of inertia it is the number of negative pivots of an ``L D L^T`` factorisation
    of ``K - sigma M``, ``sigma = (2 pi freq_Hz)^2``: one factorisation, no eigen-solve, and unlike
    an eigen-solver it cannot miss a mode.  Returns ``None`` when the count is not reliable
    (:func:`count_negative_pivots`).
    """
    A = (Kf - (TWO_PI * float(freq_Hz)) ** 2 * Mf).tocsr()
    if available_backend(backend) == "pardiso":
        A = sp.triu(A, format="csr")  # the whole matrix is dropped before PARDISO runs
        return count_negative_pivots(A, backend, ordering, upper=True)
    return count_negative_pivots(A, backend)


def count_pencil_modes_below(pencil, kc: dict, mc: dict, freq_Hz: float, backend: str = "auto") -> int | None:
    """:func:`count_modes_below` for a :class:`jointid.fe.pencil.FreePencil` (upper triangle assembled
    directly, cached ordering), as :func:`factorize_pencil` factorises it."""
    sigma = (TWO_PI * float(freq_Hz)) ** 2
    if available_backend(backend) == "pardiso":
        return count_negative_pivots(pencil.shifted_upper(kc, mc, sigma), backend, pencil.ordering, upper=True)
    return count_negative_pivots(pencil.shifted(kc, mc, sigma), backend)


def count_negative_pivots(A: sp.csr_matrix, backend: str = "auto", ordering: np.ndarray | None = None,
                          upper: bool = False) -> int | None:
    """Number of negative eigenvalues of the symmetric matrix ``A`` (its upper triangle with
    ``upper``, PARDISO only) from the signs of ``D`` in ``A = L D L^T``.

    PARDISO (symmetric indefinite, Bunch-Kaufman pivots) reports the inertia directly; SuperLU keeps
    diagonal pivots under a symmetric permutation, so the signs of ``U``'s diagonal are those of
    ``D``.  ``None`` when the count is not reliable: SuperLU had to leave the diagonal, or PARDISO
    perturbed a pivot (``A`` singular to round-off).
    """
    if available_backend(backend) == "pardiso":
        from pypardiso.pardiso_wrapper import PyPardisoError

        try:
            fac = _PardisoFactor(A, upper=upper, ordering=ordering, indefinite=True)
        except (PyPardisoError, ModelError):  # the factorisation failed: no count
            return None
        fac.free()
        return None if fac.n_perturbed else fac.inertia[1]
    try:
        lu = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except RuntimeError:  # exactly singular
        return None
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return None
    return int(np.count_nonzero(lu.U.diagonal() < 0))


# ------------------------------------------------------------------ eigen-solve
@dataclass
class Modes:
    """Mass-normalised modes: ``freqs_Hz (n,)``, ``phi (n_dofs, n)`` with zeros at fixed DOFs."""

    freqs_Hz: np.ndarray
    phi: np.ndarray
    sturm: "SturmCheck | None" = None  # completeness check of the solve (solve_model(certify=True))
    residual: float | None = None  # largest relative residual of the modes (solve_model(certify=True))

    @property
    def omega2(self) -> np.ndarray:
        return (TWO_PI * self.freqs_Hz) ** 2


@dataclass(frozen=True)
class SturmCheck:
    """Completeness of a modal solve: the model has ``count`` eigenvalues below ``freq_Hz`` (Sturm
    count, :func:`count_modes_below`; ``None``: not available) and the solve found ``found``;
    ``recovered``: modes a first Lanczos run missed, found by a second solve (:func:`solve_model`)."""

    freq_Hz: float
    count: int | None
    found: int
    recovered: int = 0

    @property
    def complete(self) -> bool | None:
        return None if self.count is None else self.count == self.found

    def describe(self) -> str:
        if self.count is None:
            return f"Sturm check at {self.freq_Hz:.1f} Hz not available (no reliable inertia)"
        state = "all found" if self.complete else f"the solve found {self.found}"
        return f"Sturm check: {self.count} modes below {self.freq_Hz:.1f} Hz, {state}"


def check_frequency(freqs_Hz, min_gap: float = 1e-6) -> float | None:
    """Where to count the modes of a solve: midway between the highest two neighbouring frequencies
    that differ by more than ``min_gap`` (relative), so that the count is taken well away from any
    eigenvalue (the modes below it are then all expected among the solved ones; ``None`` if there is
    no such pair)."""
    f = np.sort(np.asarray(freqs_Hz, float))
    for i in range(len(f) - 1, 0, -1):
        if f[i] - f[i - 1] > min_gap * max(abs(f[i]), 1e-30):
            return 0.5 * float(f[i - 1] + f[i])
    return None


def sturm_check(Kf, Mf, freqs_Hz, freq_Hz: float, backend: str = "auto",
                ordering: np.ndarray | None = None) -> SturmCheck:
    """Compare the Sturm count below ``freq_Hz`` with the solved frequencies below it."""
    count = count_modes_below(Kf, Mf, freq_Hz, backend, ordering)
    return SturmCheck(float(freq_Hz), count, int(np.count_nonzero(np.asarray(freqs_Hz) < freq_Hz)))


def shift_sigma(shift_Hz: float) -> float:
    """Spectral shift ``sigma`` (rad^2/s^2) of ``solver.shift_Hz`` (negative Hz: a shift below zero)."""
    return -abs(TWO_PI * shift_Hz) ** 2 if shift_Hz <= 0 else (TWO_PI * shift_Hz) ** 2


def solve_modes(K: sp.spmatrix, M: sp.spmatrix, n_modes: int, *, shift_Hz: float = -10.0,
                fixed: np.ndarray | None = None, backend: str = "auto", tol: float = 0.0,
                factor=None, ordering: np.ndarray | None = None, v0_seed: int | None = None) -> Modes:
    # many parameters: the eigen solver's options (shift, backend, tolerance, factor, ordering, seed)
    """Lowest ``n_modes`` eigenpairs of ``K phi = w^2 M phi`` by shift-invert Lanczos.

    ``shift_Hz`` < 0 places the shift below zero, so ``K - sigma M`` is positive definite even with
    rigid-body modes, and a shift can never hit an eigenvalue.  ``fixed`` DOFs are removed (clamped).
    ``factor``: a factorisation of ``K - sigma M`` on the free DOFs (:func:`factorize`) to reuse; it is
    then left to the caller to free.  ``ordering``: see :func:`factorize`.  ``v0_seed``: see
    :func:`shift_invert_lanczos`.
    """
    free = free_dofs(K.shape[0], fixed)
    return _solve_free(restrict(K, free), restrict(M, free), free, K.shape[0], n_modes, shift_Hz,
                       backend, tol, factor, ordering, v0_seed)


def solve_model(model, kc: dict, mc: dict, n_modes: int, *, shift_Hz: float = -10.0,
                backend: str = "auto", certify: bool = False, tol: float = 0.0) -> Modes:
    """:func:`solve_modes` of an affine model (:class:`jointid.fe.affine.AffineModel`) at coefficients ``kc``, ``mc``, with the model's cached ordering.
    The full-size matrices are restricted to the free DOFs and dropped before the factorisation
    (about 0.3 GB less peak memory at 10^5 DOFs than holding both).

    ``tol``: the Lanczos tolerance (:func:`shift_invert_lanczos`; :data:`SURVEY_TOL` where the answer is not a
    certificate).  ``certify``: count the model's modes below a frequency between the two highest solved ones
    (:func:`count_modes_below`, one more factorisation) and compare with the solve
    (``Modes.sturm``).  Modes the Lanczos run missed are recovered by one more solve for that many
    more modes from a random start; if the counts still differ, a :class:`NumericalWarning`.  Also
    the modes' largest relative residual (:func:`jointid.fe.blocklanczos.true_residual`, ``Modes.residual``).
    """
    free = free_dofs(model.n_dofs, model.fixed)
    Kf, Mf = restrict(model.K(kc), free), restrict(model.M(mc), free)
    release_model_pages(model)
    ordering = getattr(model, "ordering", None)
    modes = _solve_free(Kf, Mf, free, model.n_dofs, n_modes, shift_Hz, backend, tol, None, ordering)
    fc = check_frequency(modes.freqs_Hz) if certify else None
    if fc is not None:
        check = sturm_check(Kf, Mf, modes.freqs_Hz, fc, backend, ordering)
        if check.count is not None and check.count > check.found:
            missed = check.count - check.found
            more = _solve_free(Kf, Mf, free, model.n_dofs, n_modes + missed, shift_Hz, backend, tol, None,
                               ordering, v0_seed=0)
            modes = Modes(more.freqs_Hz[:n_modes], more.phi[:, :n_modes])
            check = SturmCheck(fc, check.count, int(np.count_nonzero(more.freqs_Hz < fc)), missed)
        if check.complete is False:
            warnings.warn(check.describe() + ": the modal solve is not complete", NumericalWarning)
        modes.sturm = check
    if certify:
        modes.residual = true_residual(Kf, Mf, modes.omega2, modes.phi[free])
    return modes


def release_model_pages(model) -> int:
    """Drop the model file's memory-mapped pages from this process once its matrices are assembled
    (:func:`jointid.io.release_mapped`): at 2 x 10^5 DOFs the stiffness and mass terms' pages are
    about 0.5 GB of resident memory that the factorisation and the Lanczos run never touch."""
    from jointid.io import release_mapped

    terms = [*(getattr(model, "stiffness", None) or {}).values(), *(getattr(model, "mass", None) or {}).values()]
    return release_mapped([A.data for A in terms if hasattr(A, "data")])  # a model without terms: nothing


def release_heap() -> None:
    """Collect garbage and return the freed heap to the system (glibc ``malloc_trim``), so that a
    model built after another one was dropped (the edge levels, :func:`jointid.identification.polish.edge_limit_at`)
    does not stack its peak on the first one's freed but still resident memory.  Elsewhere: collect only."""
    import ctypes
    import gc

    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc
        pass


def free_dofs(n: int, fixed) -> np.ndarray:
    """The DOFs of ``range(n)`` not in ``fixed``."""
    return np.setdiff1d(np.arange(n), fixed) if fixed is not None and len(fixed) else np.arange(n)


def restrict(A: sp.spmatrix, free: np.ndarray) -> sp.csr_matrix:
    """``A`` restricted to the DOFs ``free`` (rows and columns), CSR."""
    return A[free][:, free].tocsr() if len(free) < A.shape[0] else A.tocsr()


def _solve_free(Kf, Mf, free, n, n_modes, shift_Hz, backend, tol, factor, ordering, v0_seed=None) -> Modes:
    # many parameters: the private continuation of solve_modes, its options passed through
    _check_count(n_modes, len(free))
    sigma = shift_sigma(shift_Hz)
    fac = factor if factor is not None else factorize_shifted(Kf, Mf, sigma, backend, ordering)
    try:
        vec, freqs = shift_invert_lanczos(Kf, Mf, fac, n_modes, sigma, tol, v0_seed)
    finally:
        if factor is None:
            fac.free()
    phi = np.zeros((n, n_modes))
    phi[free] = vec
    return Modes(freqs_Hz=freqs, phi=phi)


def _check_count(n_modes: int, n_free: int) -> None:
    if n_modes >= n_free - 1:
        raise ModelError(f"solver.n_modes: {n_modes} modes requested but the model has only "
                         f"{n_free} free DOFs — lower solver.n_modes or refine the mesh")


SURVEY_TOL = 1e-8
"""The Lanczos tolerance (Ritz residual relative to the eigenvalue of ``(K - sigma M)^-1 M``) of a solve whose answer
is not itself a certificate: the refined meshes of the mesh check and of the edge levels, and the harmonic band.
(The diagnosis's refined meshes keep the default: their round-off moves the path of its adaptive fits, whose
time then swings by more than this saves.)  On the thickness-halved default mesh (103 707 free DOFs, 20 modes) against
the default 1e-10: 15 block solves instead of 18, 5.7 s instead of 7.5 s; frequencies the same to 8e-16, mode
shapes to 6e-9 (mass norm); the true residual 1e-5 instead of 3e-8 (accepted up to :data:`SURVEY_RESIDUAL` times
the tolerance).  A certified solve (rule verify, the reduced solver's checks) keeps the default."""
SURVEY_RESIDUAL = 1e4
"""A returned pair's accepted true residual, relative to the Lanczos tolerance asked for (at least ``RESIDUAL_TOL``):
it still catches the wrong pairs of a singular shift (residuals of order 1)."""


def shift_invert_lanczos(Kf, Mf, fac, n_modes: int, sigma: float, tol: float = 0.0,
                         v0_seed: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Shift-invert Lanczos on the free DOFs: mass-normalised vectors with a fixed sign (largest
    component positive, for determinism) and frequencies in Hz, ascending.

    From :data:`jointid.fe.blocklanczos.MIN_DOFS` free DOFs on, block Lanczos (ten right-hand sides
    per solve, :func:`jointid.fe.blocklanczos.block_shift_invert`); below, or should it not converge,
    single-vector Lanczos (ARPACK, ``tol`` 0: machine precision), as also when a block answer's true
    residual (:func:`jointid.fe.blocklanczos.true_residual`) is above ``RESIDUAL_TOL``.  The start is uniform (ARPACK) or
    a uniform column with seeded random ones (block), random with ``v0_seed``.
    """
    found = None
    if Kf.shape[0] >= MIN_DOFS and _fits_block(n_modes, Kf.shape[0]):
        found = block_shift_invert(Mf, fac.solve, n_modes, sigma, tol=max(tol, BLOCK_TOL), seed=v0_seed)
        if found is not None and not true_residual(Kf, Mf, *found) <= max(RESIDUAL_TOL, SURVEY_RESIDUAL * tol):
            found = None  # e.g. a singular K - sigma M: single-vector Lanczos copes with it
    lam, vec = found if found is not None else _arpack(Kf, Mf, fac, n_modes, sigma, tol, v0_seed)
    order = np.argsort(lam)
    lam, vec = lam[order], vec[:, order]
    if not np.all(np.isfinite(lam)):
        raise ModelError("solver: eigenvalues are not finite — the model is singular; check supports/joints")
    if np.any(lam < -1e-6 * max(1.0, abs(lam).max())):
        warnings.warn("negative eigenvalues found: the stiffness matrix is indefinite", NumericalWarning)
    mnorm = np.sqrt(np.einsum("ij,ij->j", vec, Mf @ vec))
    vec = vec / mnorm
    # C order: ARPACK returns Fortran order, which every later sparse product would copy again
    return np.ascontiguousarray(fix_signs(vec)), np.sqrt(np.clip(lam, 0.0, None)) / TWO_PI


def fix_signs(vec: np.ndarray, rel: float = 1e-6) -> np.ndarray:
    """The columns of ``vec`` signed so that their largest component is positive; among components
    within ``rel`` of the largest magnitude (symmetric structures have equal ones, which rounding
    orders either way) the first in DOF order decides."""
    mag = np.abs(vec)
    idx = np.argmax(mag >= (1.0 - rel) * mag.max(axis=0), axis=0)
    sign = np.sign(vec[idx, np.arange(vec.shape[1])])
    sign[sign == 0] = 1.0
    return vec * sign


def _fits_block(n_modes: int, n: int) -> bool:
    """The block method's basis (:func:`jointid.fe.blocklanczos.wanted_basis`) is well below ``n``."""
    return wanted_basis(n_modes, BLOCK, n) < n // 4


def _arpack(Kf, Mf, fac, n_modes: int, sigma: float, tol: float, v0_seed: int | None):
    """Single-vector shift-invert Lanczos (ARPACK): ``(lam, vectors)``, in ARPACK's order."""
    op = spla.LinearOperator(Kf.shape, matvec=fac.solve, dtype=np.float64)
    if v0_seed is None:
        v0 = np.ones(Kf.shape[0]) / np.sqrt(Kf.shape[0])
    else:
        v0 = np.random.default_rng(v0_seed).standard_normal(Kf.shape[0])
    return spla.eigsh(Kf, k=n_modes, M=Mf, sigma=sigma, which="LM", OPinv=op, v0=v0, tol=tol)
