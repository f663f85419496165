"""FreePencil (affine matrices on one fixed pattern) and the PARDISO ordering reuse, against dense references."""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from jointid.fe import fem
from jointid.fe.modal import (available_backend, factorize_pencil, shift_invert_lanczos, shift_sigma, solve_model,
                           solve_modes)
from jointid.fe.pencil import FreePencil

N = 240


def _chain_model():
    """A clamped spring-mass chain with two affine stiffness terms (one a long-range spring that
    adds entries outside K0's pattern) and a lumped-mass term."""
    k = np.full(N, 1.0e6)
    K0 = sp.diags([np.r_[k[:-1] + k[1:], k[-1]], -k[1:], -k[1:]], [0, 1, -1], format="csr")
    m = 0.5
    M0 = sp.diags([np.full(N, 4 * m / 6), np.full(N - 1, m / 6), np.full(N - 1, m / 6)], [0, 1, -1],
                  format="csr")
    a, b = 17, 203
    K1 = sp.csr_matrix(([1.0, -1.0, -1.0, 1.0], ([a, a, b, b], [a, b, a, b])), shape=(N, N))
    K2 = sp.diags(np.r_[np.zeros(N - 40), np.ones(40)], format="csr")  # ground springs at the tip
    M1 = sp.csr_matrix(([1.0], ([120], [120])), shape=(N, N))
    return fem.Model(stiffness={"K0": K0, "K_link": K1, "K_ground": K2}, mass={"M0": M0, "M_point": M1},
                     fixed=np.array([0, 1]), probe=sp.csr_matrix((1, N)), doflocs=np.zeros((3, N // 3)),
                     dof_part=np.zeros(N // 3, dtype=int))


KC = {"K_link": 3.0e5, "K_ground": 2.0e4}
MC = {"M_point": 0.8}


@pytest.fixture(scope="module")
def model():
    return _chain_model()


def test_matrices_equal_the_sliced_affine_sums(model):
    p = FreePencil(model)
    free = np.arange(2, N)
    K = model.K(KC)[free][:, free]
    M = model.M(MC)[free][:, free]
    assert abs(p.K(KC) - K).max() == pytest.approx(0.0, abs=1e-9 * abs(K).max())
    assert abs(p.M(MC) - M).max() == pytest.approx(0.0, abs=1e-15)
    sigma = shift_sigma(-10.0)
    U = p.shifted_upper(KC, MC, sigma)
    assert abs(U - sp.triu(K - sigma * M)).max() < 1e-9 * abs(K).max()
    assert U.has_sorted_indices and (sp.tril(U, -1).nnz == 0)
    assert abs(p.shifted(KC, MC, sigma) - (K - sigma * M)).max() < 1e-9 * abs(K).max()
    # the pattern does not depend on the coefficients: a zero coefficient keeps its entries
    assert p.K({}).nnz == p.K(KC).nnz


def test_unknown_term_is_an_error(model):
    with pytest.raises(KeyError, match="K_missing"):
        FreePencil(model).K({"K_missing": 1.0})


@pytest.mark.parametrize("backend", ["scipy", "pardiso"])
def test_modes_equal_dense_reference_and_ordering_is_reused(model, backend):
    if backend == "pardiso" and available_backend("auto") != "pardiso":
        pytest.skip("pypardiso not installed")
    p = FreePencil(model)
    free = np.arange(2, N)
    lam_ref = sla.eigh(model.K(KC)[free][:, free].toarray(), model.M(MC)[free][:, free].toarray(),
                       eigvals_only=True, subset_by_index=[0, 7])
    f_ref = np.sqrt(lam_ref) / (2 * np.pi)
    sigma = shift_sigma(-10.0)
    fac = factorize_pencil(p, KC, MC, sigma, backend)
    vec, f1 = shift_invert_lanczos(p.K(KC), p.M(MC), fac, 8, sigma)
    fac.free()
    np.testing.assert_allclose(f1, f_ref, rtol=1e-9)
    assert np.all(p.expand(vec)[:2] == 0.0)
    if backend == "pardiso":
        assert p.ordering is not None and sorted(p.ordering) == list(range(1, N - 1))
    # a second point reuses the ordering and still solves exactly
    kc2 = {"K_link": 1.0e3, "K_ground": 5.0e5}
    fac = factorize_pencil(p, kc2, MC, sigma, backend)
    _, f2 = shift_invert_lanczos(p.K(kc2), p.M(MC), fac, 8, sigma)
    fac.free()
    m2_ref = solve_modes(model.K(kc2), model.M(MC), 8, fixed=model.fixed, backend="scipy")
    np.testing.assert_allclose(f2, m2_ref.freqs_Hz, rtol=1e-9)
    # the model-level solve (restrict, drop the full matrices, factorise) gives the same modes
    m2_model = solve_model(model, kc2, MC, 8, backend=backend)
    np.testing.assert_allclose(m2_model.freqs_Hz, m2_ref.freqs_Hz, rtol=1e-9)
    assert np.abs(np.abs(np.sum(m2_model.phi * (model.M(MC) @ m2_ref.phi), axis=0)) - 1).max() < 1e-8
    fac = factorize_pencil(p, kc2, MC, sigma, backend)
    b = np.random.default_rng(0).standard_normal((N - 2, 3))
    x = fac.solve(b)
    fac.free()
    assert np.linalg.norm(p.shifted(kc2, MC, shift_sigma(-10.0)) @ x - b) < 1e-10 * np.linalg.norm(b)


def test_cached_model_ordering_serves_any_parameter_point(tmp_path):
    from jointid.fe.modal import factorize_shifted, model_ordering
    from jointid.fe.model import load_model, save_model

    if available_backend("auto") != "pardiso":
        pytest.skip("pypardiso not installed")
    model = _chain_model()
    order = model_ordering(model)
    assert sorted(order) == list(range(1, N - 1))  # a permutation of the free DOFs, 1-based
    model.ordering = order
    save_model(model, tmp_path / "m.npz")
    assert np.array_equal(load_model(tmp_path / "m.npz").ordering, order)
    free = np.arange(2, N)
    kc = {"K_link": 0.0, "K_ground": 7.0e3}  # a zero term: a smaller pattern, same ordering
    Kf, Mf = model.K(kc)[free][:, free], model.M(MC)[free][:, free]
    fac = factorize_shifted(Kf, Mf, shift_sigma(-10.0), "pardiso", order)
    b = np.random.default_rng(1).standard_normal(N - 2)
    x = fac.solve(b)
    fac.free()
    assert np.linalg.norm((Kf - shift_sigma(-10.0) * Mf) @ x - b) < 1e-10 * np.linalg.norm(b)


def test_the_layout_is_made_once_when_first_needed_and_changes_no_product(model):
    import threading

    p = FreePencil(model)
    assert not p._laid_out  # restricting the terms is all a new pencil does
    X = np.random.default_rng(0).standard_normal((N - 2, 3))
    before = p.K_terms["K0"] @ X
    threads = [threading.Thread(target=p.layout) for _ in range(4)]  # a factorisation thread and the caller
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert p._laid_out
    aligned = p.K_terms["K0"]
    assert aligned.nnz == p.pattern.nnz > model.stiffness["K0"][2:, 2:].nnz  # K0 on the union pattern
    assert np.array_equal(aligned @ X, before)  # its explicit zeros change no product
    p.layout()
    assert p.K_terms["K0"] is aligned  # made once
    fresh = FreePencil(model)
    assert np.array_equal(fresh.K(KC).toarray(), p.K(KC).toarray())  # the first assembly lays it out
