"""Block shift-invert Lanczos (jointid.fe.blocklanczos) against closed forms and ARPACK, its
restarts, its fallback, and the sign convention of mode shapes."""

import numpy as np
import pytest
import scipy.sparse as sp

import jointid.fe.blocklanczos as bl
import jointid.fe.modal as fm
from jointid.fe.modal import factorize, fix_signs, shift_invert_lanczos, shift_sigma

K_SPRING, MASS = 2.0e7, 0.5
RTOL = 1e-8  # the long chains' condition number (~10^7 at 3000 masses) times the machine epsilon


def chain(n: int, copies: int = 1):
    """``copies`` identical fixed-free chains of ``n`` masses on springs (block diagonal)."""
    main = np.full(n, 2.0 * K_SPRING)
    main[-1] = K_SPRING
    K1 = sp.diags([main, np.full(n - 1, -K_SPRING), np.full(n - 1, -K_SPRING)], [0, -1, 1])
    K = sp.block_diag([K1] * copies, format="csr")
    return K, sp.identity(n * copies, format="csr") * MASS


def chain_eigenvalues(n: int, k: int) -> np.ndarray:
    """Closed form of the fixed-free chain: lam_j = 4 k/m sin^2((2j-1) pi / (2 (2n+1)))."""
    j = np.arange(1, k + 1)
    return 4.0 * K_SPRING / MASS * np.sin((2 * j - 1) * np.pi / (2 * (2 * n + 1))) ** 2


def solve_block(K, M, k, **kw):
    sigma = shift_sigma(-10.0)
    fac = factorize((K - sigma * M).tocsr(), "scipy")
    return bl.block_shift_invert(M, fac.solve, k, sigma, **kw), fac, sigma


def test_chain_against_closed_form():
    n, k = 3000, 12
    K, M = chain(n)
    (lam, X), _, _ = solve_block(K, M, k)
    assert np.allclose(lam, chain_eigenvalues(n, k), rtol=RTOL, atol=0)
    assert np.allclose(X.T @ (M @ X), np.eye(k), atol=1e-10)  # M-orthonormal
    res = np.linalg.norm(K @ X - (M @ X) * lam, axis=0) / np.linalg.norm(K @ X, axis=0)
    assert res.max() < 1e-6


def test_restarts_reach_the_same_modes():
    """A basis of the wanted modes and three blocks forces thick restarts; the answer is unchanged."""
    n, k = 3000, 12
    K, M = chain(n)
    (lam_small, _), _, _ = solve_block(K, M, k, block=4, max_basis=k + 12)
    assert np.allclose(lam_small, chain_eigenvalues(n, k), rtol=RTOL, atol=0)


def test_repeated_eigenvalues_are_all_found():
    """Two identical chains: every eigenvalue is double, and a single-vector start sees one copy
    per pair; the block start finds both."""
    n, k = 1500, 10
    K, M = chain(n, copies=2)
    (lam, X), _, _ = solve_block(K, M, k)
    assert np.allclose(lam, np.repeat(chain_eigenvalues(n, k // 2), 2), rtol=RTOL, atol=0)
    assert np.linalg.matrix_rank(X.T @ (M @ X)) == k


def test_not_converging_returns_none():
    n, k = 3000, 12
    K, M = chain(n)
    (found, _, _) = solve_block(K, M, k, block=4, max_basis=k + 8, tol=1e-300)
    assert found is None


def test_fallback_to_arpack_when_the_block_method_fails(monkeypatch):
    """A block solve made to fail (an unreachable tolerance) falls back to ARPACK with the same modes."""
    n, k = 6000, 8
    K, M = chain(n)
    sigma = shift_sigma(-10.0)
    fac = factorize((K - sigma * M).tocsr(), "scipy")
    calls = []
    real = bl.block_shift_invert
    monkeypatch.setattr(fm, "MIN_DOFS", 5000)  # the block method at this size

    def failing(*a, **kw):
        kw["tol"] = 1e-300
        out = real(*a, **kw)
        calls.append(out)
        return out

    monkeypatch.setattr(fm, "block_shift_invert", failing)
    vec, f = shift_invert_lanczos(K, M, fac, k, sigma)
    assert calls == [None]  # tried, failed, fell back
    assert np.allclose((2 * np.pi * f) ** 2, chain_eigenvalues(n, k), rtol=RTOL, atol=0)


def test_block_and_arpack_agree_through_shift_invert_lanczos(monkeypatch):
    n, k = 6000, 10
    K, M = chain(n)
    sigma = shift_sigma(-10.0)
    fac = factorize((K - sigma * M).tocsr(), "scipy")
    monkeypatch.setattr(fm, "MIN_DOFS", 5000)  # the block method at this size
    used = []
    monkeypatch.setattr(fm, "block_shift_invert", lambda *a, **kw: used.append(1) or bl.block_shift_invert(*a, **kw))
    vb, fb = shift_invert_lanczos(K, M, fac, k, sigma)
    assert used == [1]
    monkeypatch.setattr(fm, "MIN_DOFS", 10**9)  # ARPACK only
    va, fa = shift_invert_lanczos(K, M, fac, k, sigma)
    assert np.allclose(fb, fa, rtol=1e-12, atol=0)
    assert np.allclose(vb, va, atol=1e-8 * np.abs(va).max())  # same vectors, same signs


def test_a_survey_tolerance_keeps_the_modes_in_fewer_solves(monkeypatch):
    """The looser tolerance of a solve that is no certificate (fe.modal.SURVEY_TOL: refined meshes, the
    harmonic band): accepted by the block method (no fallback), the frequencies still the closed form's,
    the vectors the default's to 1e-7 (mass norm), in fewer block solves."""
    n, k = 1500, 10  # conditioned so that the default tolerance's true residual passes RESIDUAL_TOL (8e-8)
    K, M = chain(n)
    sigma = shift_sigma(-10.0)
    fac = factorize((K - sigma * M).tocsr(), "scipy")
    monkeypatch.setattr(fm, "MIN_DOFS", 1000)  # the block method at this size
    monkeypatch.setattr(fm, "_arpack", lambda *a, **kw: pytest.fail("fell back to ARPACK"))
    solves = []

    class Counted:
        def solve(self, b):
            solves.append(b.shape[1])
            return fac.solve(b)

    v0, f0 = shift_invert_lanczos(K, M, Counted(), k, sigma)
    n_default, solves[:] = len(solves), []
    v1, f1 = shift_invert_lanczos(K, M, Counted(), k, sigma, fm.SURVEY_TOL)
    assert len(solves) < n_default
    assert np.allclose((2 * np.pi * f1) ** 2, chain_eigenvalues(n, k), rtol=RTOL, atol=0)
    D = v1 - v0
    assert np.sqrt(np.einsum("ij,ij->j", D, M @ D)).max() < 1e-7


@pytest.mark.parametrize("eps", [1e-12, -1e-12])
def test_sign_does_not_depend_on_rounding_between_equal_components(eps):
    """Symmetric structures give components of equal magnitude; rounding orders them either way,
    the sign convention must not follow it."""
    v = np.array([[0.3], [-0.7 * (1 + eps)], [0.7], [0.1]])
    out = fix_signs(v)
    assert out[1, 0] > 0  # the first of the two (nearly) largest components is made positive
    assert np.allclose(np.abs(out), np.abs(v))
