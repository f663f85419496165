"""The reduced solver's full-space checks: points checked together, and a point certified on a smaller
basis not checked again (Poincaré: on a larger subspace every Ritz value moves towards the exact one)."""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from jointid.fe import fem
from jointid.fe.reduced import ReducedSolver

N = 300
TWO_PI = 2 * np.pi


def _chain():
    """A clamped chain of springs and masses with a ground-spring term at the tip and a point mass."""
    k = np.full(N, 1.0e6)
    K0 = sp.diags([np.r_[k[:-1] + k[1:], k[-1]], -k[1:], -k[1:]], [0, 1, -1], format="csr")
    M0 = sp.diags([np.full(N, 4 / 6), np.full(N - 1, 1 / 6), np.full(N - 1, 1 / 6)], [0, 1, -1], format="csr")
    K1 = sp.diags(np.r_[np.zeros(N - 60), np.ones(60)], format="csr")
    M1 = sp.csr_matrix(([1.0], ([150], [150])), shape=(N, N))
    return fem.Model(stiffness={"K0": K0, "K_ground": K1}, mass={"M0": M0, "M_point": M1},
                     fixed=np.array([0]), probe=sp.csr_matrix(np.eye(N)[::30]), doflocs=np.zeros((3, N // 3)),
                     dof_part=np.zeros(N // 3, dtype=int))


def _exact_Hz(model, kc, mc, n):
    free = np.setdiff1d(np.arange(N), model.fixed)
    K = (model.stiffness["K0"] + kc.get("K_ground", 0.0) * model.stiffness["K_ground"]).toarray()[np.ix_(free, free)]
    M = (model.mass["M0"] + mc.get("M_point", 0.0) * model.mass["M_point"]).toarray()[np.ix_(free, free)]
    return np.sqrt(sla.eigh(K, M, eigvals_only=True, subset_by_index=[0, n - 1])) / TWO_PI


REF = ({"K_ground": 1e4}, {"M_point": 0.5})
NEAR = ({"K_ground": 1.01e4}, {"M_point": 0.5})
NEAR2 = ({"K_ground": 1.02e4}, {"M_point": 0.52})
FAR = ({"K_ground": 3e5}, {"M_point": 20.0})
N_MODES = 6


@pytest.fixture()
def model():
    return _chain()


def _solver(model):
    return ReducedSolver(model, *REF, N_MODES, [({"K_ground": 1.0}, {}), ({}, {"M_point": 1.0})], backend="scipy")


def test_a_point_certified_on_a_smaller_basis_is_not_checked_again(model):
    rs = _solver(model)
    first = rs.solve(*NEAR, N_MODES)
    assert first.error <= rs.tol
    checks, r0 = rs.n_checks, rs.basis.r
    rs.solve(*FAR, N_MODES)  # the basis grows
    assert rs.basis.r > r0
    again = rs.solve(*NEAR, N_MODES)
    assert rs.n_checks == checks + 1  # the far point's check only
    assert rs.n_checks_skipped == 1 and again.error == first.error
    # Poincaré: on the larger basis no Ritz value is higher, none below the exact eigenvalue
    exact = _exact_Hz(model, *NEAR, N_MODES)
    assert np.all(again.freqs_Hz <= first.freqs_Hz * (1 + 1e-12))
    assert np.all(again.freqs_Hz >= exact * (1 - 1e-12))
    assert np.max(np.abs(again.freqs_Hz / exact - 1)) < 1e-6
    rs.solve(*NEAR, N_MODES, recheck=True)  # a reported point is checked afresh on request
    assert rs.n_checks == checks + 2


def test_a_point_checked_to_a_looser_tolerance_is_checked_again_after_tightening(model):
    """The hypotheses' search runs at a looser tolerance than their certificate: a point (and a state pair)
    accepted at the looser one is not taken as checked at the tighter one."""
    rs = ReducedSolver(model, *REF, N_MODES, [({"K_ground": 1.0}, {}), ({}, {"M_point": 1.0})], backend="scipy",
                       tol=1e-1)
    loose = rs.solve(*FAR, N_MODES)
    pair = rs.solve_many([NEAR, NEAR2], N_MODES)
    assert loose.error <= 1e-1 and all(p.error <= 1e-1 for p in pair)
    assert rs.solve(*FAR, N_MODES) is loose  # the same tolerance: the memo answers
    checks = rs.n_checks
    rs.tighten(1e-9)
    rs.tighten(1e-3)  # never loosened again
    assert rs.tol == 1e-9
    tight = rs.solve(*FAR, N_MODES)
    again = rs.solve_many([NEAR, NEAR2], N_MODES)
    assert rs.n_checks > checks
    for pt, sol in ((FAR, tight), (NEAR, again[0]), (NEAR2, again[1])):
        assert sol.error <= 1e-9
        assert np.max(np.abs(sol.freqs_Hz / _exact_Hz(model, *pt, N_MODES) - 1)) < 1e-8
    assert np.max(np.abs(loose.freqs_Hz / _exact_Hz(model, *FAR, N_MODES) - 1)) > 1e-8  # the looser answer was looser


def test_points_are_checked_together_with_one_sparse_solve(model):
    rs = _solver(model)
    calls = []
    solve = rs.fac.solve
    rs.fac.solve = lambda b: (calls.append(b.shape), solve(b))[1]
    sols = rs.solve_many([NEAR, NEAR2], N_MODES)
    assert calls == [(N - 1, 2 * N_MODES)]  # one solve takes both points' residuals
    single = _solver(model)
    for pt, sol in zip((NEAR, NEAR2), sols):
        assert sol.error <= rs.tol
        ref = single.solve(*pt, N_MODES)
        assert np.allclose(sol.freqs_Hz, ref.freqs_Hz, rtol=1e-12)
        assert np.max(np.abs(sol.freqs_Hz / _exact_Hz(model, *pt, N_MODES) - 1)) < 1e-6


def test_a_point_failing_the_joint_check_is_refined_alone(model):
    rs = _solver(model)
    r0 = rs.basis.r
    near, far = rs.solve_many([NEAR, FAR], N_MODES)
    assert rs.basis.r > r0 and rs.n_refine > 0
    for pt, sol in ((NEAR, near), (FAR, far)):
        assert sol.error <= rs.tol
        assert np.max(np.abs(sol.freqs_Hz / _exact_Hz(model, *pt, N_MODES) - 1)) < 1e-6


def test_a_sturm_count_at_a_point_is_made_once_and_kept_with_the_subspace(model, monkeypatch, tmp_path):
    from jointid.fe import certify, warmstart

    counts = []
    real = certify.count_pencil_modes_below
    monkeypatch.setattr(certify, "count_pencil_modes_below", lambda *a, **k: (counts.append(a[3]), real(*a, **k))[1])
    rs = _solver(model)
    lines = []
    rs.log = lines.append
    assert rs.verify(*NEAR, N_MODES) <= rs.tol
    assert rs.verify(*NEAR, N_MODES) <= rs.tol
    assert len(counts) == 1 and "counted before at this point" in lines[-1]
    rs.verify(*NEAR2, N_MODES)  # another point: counted
    assert len(counts) == 2
    # the count is the model's at those coefficients: kept with the subspace, used by the next run
    warmstart.save(tmp_path / "s.npz", rs, model)
    kept = warmstart.load(tmp_path / "s.npz", model, N - 1)[0]
    warm = ReducedSolver(model, *REF, N_MODES, basis=kept, backend="scipy")
    assert warm.verify(*NEAR2, N_MODES) <= warm.tol and len(counts) == 2
    # a count below the wrong frequency is not taken: the Ritz values must bracket it
    warm.sturm_counts = {k: [(1.0, c) for _, c in v] for k, v in warm.sturm_counts.items()}
    warm.verify(*NEAR2, N_MODES)
    assert len(counts) == 3


def test_single_precision_base_products_leave_the_error_estimate_unchanged(model):
    """``K0 V`` and ``M0 V`` are kept in single precision (jointid.fe.basis): the check's estimate
    agrees with the one from double-precision sparse products to well within what a check decides."""
    from jointid.fe import certify

    rs = _solver(model)
    assert rs.basis.KV.dtype == np.float32
    for pt in (NEAR, NEAR2, FAR):
        single = certify.check_points(rs, [pt], N_MODES)[0]
        kept = rs.basis._KV, rs.basis._MV
        rs.basis._KV = rs.basis._MV = None  # the residuals from the sparse terms, in double precision
        double = certify.check_points(rs, [pt], N_MODES)[0]
        rs.basis._KV, rs.basis._MV = kept
        np.testing.assert_allclose(single.err, double.err, rtol=1e-3, atol=1e-12)
        # and it stays an estimate of the true eigenvalue error: never below it by more than round-off
        # (conservative far from the reference, where the shift is far from the eigenvalue)
        exact = (TWO_PI * _exact_Hz(model, *pt, N_MODES)) ** 2
        true = (single.lam[:N_MODES] - exact) / exact
        assert np.all(single.err >= 0.5 * true - 1e-12) and np.all(single.err <= 5.0 * true + 1e-11)


def test_ritz_pairs_asked_again_on_the_same_basis_come_from_the_memo(monkeypatch):
    rs = ReducedSolver(_chain(), *REF, N_MODES, [({"K_ground": 1.0}, {}), ({}, {"M_point": 1.0})], backend="scipy")
    calls = []
    eigh = sla.eigh
    monkeypatch.setattr(sla, "eigh", lambda *a, **k: calls.append(1) or eigh(*a, **k))
    lam, Y = rs._ritz(*NEAR, N_MODES)
    Y[:] = 0.0  # a caller's change of its copy reaches nobody else
    lam2, Y2 = rs._ritz(*NEAR, N_MODES)
    assert len(calls) == 1 and np.array_equal(lam2, lam) and np.abs(Y2).max() > 0
    rs._ritz(*NEAR, N_MODES + 1)  # another mode count: another question
    assert len(calls) == 2
    fresh = eigh(rs._grouped(NEAR[0], rs.Kr, "K0"), rs._grouped(NEAR[1], rs.Mr, "M0"), check_finite=False,
                 subset_by_index=[0, N_MODES - 1], driver="gvx")
    assert np.array_equal(fresh[0], lam2) and np.array_equal(fresh[1], Y2)  # the same bits as a fresh solve
    rs._append(np.random.default_rng(0).standard_normal((N - 1, 1)))  # the basis grew: asked afresh
    rs._ritz(*NEAR, N_MODES)
    assert len(calls) == 3


@pytest.mark.parametrize("near", [1.0, 1e-2, 1e-4], ids=["new", "partly-known", "mostly-known"])
def test_a_grown_basis_stays_mass_orthonormal_and_its_projections_exact(model, near):
    """Enrichment vectors new to the basis, or lying mostly in it (Gram eigenvalues about 1e-6 after the
    Gram-Schmidt passes, which the normalisation amplifies), keep the basis M_ref-orthonormal and the
    projected terms those of the basis, to round-off; vectors already in it add nothing."""
    rs = _solver(model)
    rng = np.random.default_rng(1)
    V0 = rs.V.copy()
    W = V0 @ rng.standard_normal((V0.shape[1], 3)) + near * rng.standard_normal((V0.shape[0], 3))
    W = np.hstack([W, W[:, :1] + W[:, 1:2]])  # and a dependent column, dropped
    added = rs._append(W)
    assert added == 3
    assert rs._append(rs.V @ rng.standard_normal((rs.V.shape[1], 2))) == 0  # nothing new: nothing added
    V, M = rs.V, rs.M_ref
    assert np.max(np.abs(V.T @ (M @ V) - np.eye(V.shape[1]))) < 1e-11
    np.testing.assert_allclose(rs.Kr["K0"], V.T @ (rs.K_terms["K0"] @ V), rtol=0, atol=1e-9 * np.abs(rs.Kr["K0"]).max())
    np.testing.assert_allclose(rs.Mr["M_point"], V.T @ (rs.M_terms["M_point"] @ V), rtol=0, atol=1e-12)


def test_the_sensitivities_of_several_directions_are_each_directions_own(model):
    """Each term's energy formed once for all directions gives every direction's sensitivity bit for bit."""
    rs = _solver(model)
    sol = rs.solve(*NEAR, N_MODES)
    dirs = [({"K_ground": 1.0}, {}), ({}, {"M_point": 1.0}), ({"K_ground": 2.5}, {"M_point": -0.5}), ({}, {})]
    together = rs.sensitivities(sol, dirs)
    Y = np.vstack([sol.Y, np.zeros((rs.V.shape[1] - sol.Y.shape[0], sol.Y.shape[1]))])
    for (dkc, dmc), got in zip(dirs, together):
        want = np.zeros(Y.shape[1])  # d lambda = y^T (dK - lambda dM) y, term by term in the same order
        for name, c in dkc.items():
            want += c * np.einsum("ij,ij->j", Y, rs.Kr[name] @ Y)
        for name, c in dmc.items():
            want -= c * sol.lam * np.einsum("ij,ij->j", Y, rs.Mr[name] @ Y)
        assert np.array_equal(got, want)
    assert not together[-1].any()
    # and the first direction against a central difference of the exact eigenvalues
    h = 1e-3 * NEAR[0]["K_ground"]
    up, down = ({"K_ground": NEAR[0]["K_ground"] + h}, NEAR[1]), ({"K_ground": NEAR[0]["K_ground"] - h}, NEAR[1])
    fd = ((TWO_PI * _exact_Hz(model, *up, N_MODES)) ** 2 - (TWO_PI * _exact_Hz(model, *down, N_MODES)) ** 2) / (2 * h)
    np.testing.assert_allclose(together[0], fd, rtol=1e-4)
