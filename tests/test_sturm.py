"""Sturm counts (modes below a frequency from the inertia of K - sigma M) and the completeness check
of modal solves that rests on them."""

import warnings

import numpy as np
import pytest
import scipy.linalg as la
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from jointid.errors import NumericalWarning
from jointid.response.drive_point import solve_band_modes
from jointid.fe.modal import available_backend, check_frequency, count_modes_below, solve_model, solve_modes

BACKENDS = ["scipy"] + (["pardiso"] if available_backend("auto") == "pardiso" else [])
K_SPRING, MASS = 1.0e6, 0.5  # N/m, kg


def chain(n: int):
    """Masses on springs, both ends fixed: f_j = 2 sqrt(k/m) sin(j pi / (2 (n + 1))) / 2 pi."""
    K = sp.diags([np.full(n, 2 * K_SPRING), np.full(n - 1, -K_SPRING), np.full(n - 1, -K_SPRING)],
                 [0, 1, -1], format="csr")
    M = sp.diags(np.full(n, MASS), format="csr")
    f = 2 * np.sqrt(K_SPRING / MASS) * np.sin(np.arange(1, n + 1) * np.pi / (2 * (n + 1))) / (2 * np.pi)
    return K, M, f


def twin_chains(n: int):
    """Two identical uncoupled chains: every frequency twice.  A Lanczos run from the uniform start
    vector only ever sees the in-phase half of them (the two halves stay equal to the last bit)."""
    K1, M1, f = chain(n)
    return sp.block_diag([K1, K1], format="csr"), sp.block_diag([M1, M1], format="csr"), np.sort(np.tile(f, 2))


class _Pencil:
    """The part of the model interface that :func:`solve_model` uses, for a fixed pencil."""

    def __init__(self, K, M):
        self._K, self._M = K, M
        self.n_dofs = K.shape[0]
        self.fixed = np.array([], dtype=np.int64)

    def K(self, kc):
        return self._K

    def M(self, mc):
        return self._M


@pytest.mark.parametrize("backend", BACKENDS)
def test_sturm_count_of_a_spring_chain_equals_the_analytic_count(backend):
    K, M, f = chain(60)
    mids = np.concatenate([[0.5 * f[0]], 0.5 * (f[:-1] + f[1:]), [2 * f[-1]]])
    counts = [count_modes_below(K, M, fc, backend) for fc in mids]
    assert counts == list(range(61))


@pytest.mark.parametrize("backend", BACKENDS)
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(4, 40))
def test_sturm_count_matches_dense_eigenvalues_of_random_pencils(backend, seed, n):
    rng = np.random.default_rng(seed)
    B = sp.random(n, n, density=0.3, random_state=rng) + sp.eye(n)
    K = (B @ B.T + 0.1 * sp.eye(n)).tocsr()
    M = sp.diags(rng.uniform(0.5, 2.0, n), format="csr")
    lam = la.eigh(K.toarray(), M.toarray(), eigvals_only=True)
    f = np.sqrt(lam) / (2 * np.pi)
    fc = float(np.exp(rng.uniform(np.log(0.5 * f[0]), np.log(2 * f[-1]))))
    if np.min(np.abs(f - fc)) < 1e-6 * fc:  # on an eigenvalue: the count is undefined
        return
    count = count_modes_below(K, M, fc, backend)
    assert count is None or count == int(np.sum(f < fc))
    if backend == "pardiso":
        assert count is not None


@pytest.mark.parametrize("backend", BACKENDS)
def test_certified_solve_recovers_the_modes_a_lanczos_run_missed(backend):
    K, M, f = twin_chains(80)
    plain = solve_modes(K, M, 6, backend=backend)
    # the reference failure: the uniform start misses every second copy of a repeated frequency
    assert np.allclose(plain.freqs_Hz, f[::2][:6], rtol=1e-9)
    assert count_modes_below(K, M, check_frequency(plain.freqs_Hz), backend) > 5
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumericalWarning)
        modes = solve_model(_Pencil(K, M), {}, {}, 6, backend=backend, certify=True)
    assert np.allclose(modes.freqs_Hz, f[:6], rtol=1e-9)
    assert modes.sturm.complete
    assert modes.sturm.count == modes.sturm.found == int(np.sum(f < modes.sturm.freq_Hz))
    assert "all found" in modes.sturm.describe()


@pytest.mark.parametrize("backend", BACKENDS)
def test_band_modes_are_counted_first_and_solved_at_once(backend):
    K, M, f = chain(80)
    modes = solve_band_modes(K, M, 50.0, n_start=6, backend=backend)  # all modes below 2.5 x 50 Hz
    below = f[f < 125.0]
    assert len(modes.freqs_Hz) == len(below) + 2  # the count and two above it, in one solve
    assert np.allclose(modes.freqs_Hz, f[: len(below) + 2], rtol=1e-9)


@pytest.mark.parametrize("backend", BACKENDS)
def test_band_modes_missed_by_the_first_solve_are_recovered(backend):
    K, M, f = twin_chains(80)
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumericalWarning)
        modes = solve_band_modes(K, M, 50.0, n_start=6, backend=backend)
    below = f[f < 125.0]
    assert np.allclose(modes.freqs_Hz[: len(below)], below, rtol=1e-9)


def test_check_frequency_lies_between_the_two_highest_distinct_frequencies():
    assert check_frequency([1.0, 2.0, 4.0, 4.0]) == pytest.approx(3.0)
    assert check_frequency([1.0, 2.0, 4.0, 4.0 * (1 + 1e-9)]) == pytest.approx(3.0)  # a pair, not a gap
    assert check_frequency([5.0]) is None
    assert check_frequency([5.0, 5.0]) is None
