"""The error budget of the diagnosis's fits (docs/effects.md, "Every known error counted", "Blocks"):
frequency and shape rows judged as two blocks, each with its own model error; known errors beside the
noise; cluster-robust intervals where shapes are fitted. Analytic references on linear models."""

from types import SimpleNamespace

import numpy as np
import pytest

from jointid.diagnosis.results import Evaluation, Fit, block_error, chi2_at, whitener
from jointid.diagnosis.criteria import chi2_p_value
from jointid.identification.model_error import NO_MODEL_ERROR, ModelError, estimate, mode_correlation


def _fit(r, J, rows, sigma, known=None, n_scales=0, known_corr=None):
    r, J = np.asarray(r, float), np.asarray(J, float)
    ev = Evaluation(x=np.zeros(J.shape[1]), r=r, J=J, solutions=[], index=[], rows=rows, f_model=[],
                    n_scales=n_scales, sigma=np.asarray(sigma, float),
                    known=None if known is None else np.asarray(known, float), known_corr=known_corr)
    return Fit(variant=SimpleNamespace(n_params=J.shape[1]), ev=ev, pairings=[])


def _two_blocks(freq_r, shape_r, s=0.01, eps=0.05):
    """A fit with frequency rows (state 0, modes 1..) and one shape row per displacement of mode 1."""
    nf, ns = len(freq_r), len(shape_r)
    rows = [(0, m + 1) for m in range(nf)] + [(0, -1)] * ns
    J = np.zeros((nf + ns, 1))
    J[:nf, 0] = 1.0
    return _fit(np.concatenate([freq_r, shape_r]), J, rows, [s] * nf + [eps] * ns, n_scales=1)


def test_each_block_gets_its_own_model_error():
    # frequencies 3x their stated noise (chi2/dof 9), shapes at their noise: the shape block cannot hide it
    rng = np.random.default_rng(1)
    freq = np.array([3.0, -3.0, 3.0, -3.0, 3.0, -3.0, 3.0])  # chi2 63 for 7 - 1 = 6 dof
    shape = rng.standard_normal(400)
    f = _two_blocks(freq, shape)
    me = f.own_error()
    assert me.c_hat == pytest.approx(63.0 / 6.0)
    # sigma_m from the closed form of one noise, no known part: s sqrt(c_hat - 1)
    assert me.sigma_model_rel == pytest.approx(0.01 * np.sqrt(63.0 / 6.0 - 1.0), rel=1e-12)
    assert me.shape is not None and me.shape.c_hat == pytest.approx(float(shape @ shape) / 399)
    # one chi-square over all rows would call this consistent with the noise; the blocks do not
    all_rows = chi2_p_value(f.chi2, len(f.ev.r) - 1 - 1)
    assert all_rows > 0.01
    assert f.p_value == pytest.approx(chi2_p_value(63.0, 6)) and f.p_value < 1e-9


def test_chi2_at_the_total_uncertainty_sums_the_blocks_at_their_own_errors():
    freq = np.array([2.0, -2.0, 2.0, -2.0, 2.0])  # chi2 20 for 4 dof: c_hat 5
    shape = np.array([1.5, -1.5] * 50)  # chi2 225 for 99 dof
    f = _two_blocks(freq, shape)
    me = f.own_error()
    # at its own model error each block's chi-square equals its degrees of freedom
    assert chi2_at(f.ev, None, me) == pytest.approx(4.0 + 99.0, rel=1e-9)
    w = np.diag(whitener(f.ev, None, me)) ** 2
    np.testing.assert_allclose(w[:5], 1 / 5.0, rtol=1e-9)
    np.testing.assert_allclose(w[5:], 99.0 / 225.0, rtol=1e-9)
    # without a model error the shape rows count at their noise
    assert chi2_at(f.ev, None, NO_MODEL_ERROR) == pytest.approx(20.0 + 225.0)


def test_a_known_error_enters_the_moment_equation_beside_the_noise():
    # e = 2 % on every row, noise 1 %, known 1 %: sigma_m^2 = e^2 n/(n-k) - s^2 - k^2
    n, k = 8, 1
    r = np.full(n, 2.0)
    est = estimate(r, 0.01, k, known_rel=np.full(n, 0.01))
    assert est.sigma_model_rel ** 2 == pytest.approx(0.02 ** 2 * n / (n - k) - 0.01 ** 2 - 0.01 ** 2, rel=1e-9)
    assert est.sigma_known_rel == pytest.approx(0.01)
    # a known error as large as the misfit leaves no model error
    assert estimate(r, 0.01, k, known_rel=np.full(n, 0.02)).sigma_model_rel == 0.0


def test_frequency_only_intervals_are_the_birge_rule():
    J = np.vstack([np.eye(2) * [2.0, 0.5], np.zeros((4, 2))])
    f = _fit([3.0, 4.0, 0, 0, 0, 0], J, [(0, m) for m in range(1, 7)], [0.01] * 6)
    np.testing.assert_allclose(f.scaled_covariance(), np.diag([0.25, 4.0]) * 25.0 / 4.0, rtol=1e-12)
    # with a per-row known error the rows are weighted by their total variance
    g = _fit([3.0, 4.0, 0, 0, 0, 0], J, [(0, m) for m in range(1, 7)], [0.01] * 6, known=[0.01, 0, 0, 0, 0, 0])
    me = g.own_error()
    w = np.full(6, 1.0)
    w[0] = 0.01 ** 2 / (0.01 ** 2 + 0.01 ** 2 + me.sigma_model_rel ** 2)
    w[1:] = 0.01 ** 2 / (0.01 ** 2 + me.sigma_model_rel ** 2)
    Jw = J * np.sqrt(w)[:, None]
    np.testing.assert_allclose(g.scaled_covariance(), np.linalg.inv(Jw.T @ Jw), rtol=1e-10)


def test_correlated_shape_rows_widen_the_interval_by_the_cluster_robust_variance():
    """One parameter moves every displacement of a mode alike.  Independent residuals: the sandwich
    agrees with the weighted covariance (factor near 1).  The same residuals made coherent within each
    mode (a shape model error, not noise): the sandwich is wider by about the cluster size."""
    rng = np.random.default_rng(7)
    n_modes, n_dof = 30, 20
    rows, sig = [], []
    for m in range(n_modes):
        rows += [(0, -(m + 1))] * n_dof
        sig += [0.05] * n_dof
    J = np.ones((n_modes * n_dof, 1))
    indep = rng.standard_normal(n_modes * n_dof)
    f = _fit(indep, J, rows, sig)
    Jf = whitener(f.ev, None, f.own_error()) @ J
    base = np.linalg.pinv(Jf.T @ Jf)
    ratio_indep = float(f.scaled_covariance()[0, 0] / base[0, 0])
    assert 1.0 <= ratio_indep < 2.0
    coherent = np.repeat(rng.standard_normal(n_modes), n_dof)  # each mode's rows move together
    g = _fit(coherent, J, rows, sig)
    Jg = whitener(g.ev, None, g.own_error()) @ J
    base_g = np.linalg.pinv(Jg.T @ Jg)
    ratio = float(g.scaled_covariance()[0, 0] / base_g[0, 0])
    assert ratio > 0.4 * n_dof, ratio


def test_block_error_reports_the_three_parts():
    f = _two_blocks(np.array([2.0, -2.0, 2.0, -2.0]), np.ones(30))
    rec = block_error(f.ev, None, 1, reference="test").record()
    for key in ("sigma_noise_pct", "sigma_known_pct", "sigma_model_pct", "shape_sigma_model_pct", "shape_c_hat"):
        assert key in rec
    assert rec["sigma_noise_pct"] == pytest.approx(1.0)


def test_the_shape_block_counts_less_when_its_rows_move_together():
    """Rao and Scott's first-order correction: coherent rows within each mode carry about one row's
    evidence per mode (design effect near the cluster size); independent rows keep their count."""
    rng = np.random.default_rng(11)
    n_modes, n_dof = 30, 20
    rows = [(0, m + 1) for m in range(n_modes)] + [(0, -(m + 1)) for m in range(n_modes) for _ in range(n_dof)]
    sig = [0.01] * n_modes + [0.05] * (n_modes * n_dof)
    J = np.ones((len(rows), 1))
    freq = rng.standard_normal(n_modes)
    indep = _fit(np.concatenate([freq, rng.standard_normal(n_modes * n_dof)]), J, rows, sig, n_scales=n_modes)
    assert 0.9 <= indep.shape_design_effect() < 1.6
    coherent = _fit(np.concatenate([freq, np.repeat(rng.standard_normal(n_modes), n_dof)]), J, rows, sig,
                    n_scales=n_modes)
    assert coherent.shape_design_effect() > 0.4 * n_dof
    # and the chi-square at the total uncertainty divides the shape block by it
    from dataclasses import replace
    me = coherent.own_error()
    de = coherent.shape_design_effect()
    me2 = replace(me, shape=replace(me.shape, design_effect=de))
    f_rows = np.arange(n_modes)
    chi_f = me.chi2_total(coherent.ev.r[f_rows], 0.01)
    assert chi2_at(coherent.ev, None, me2) - chi_f == pytest.approx((chi2_at(coherent.ev, None, me) - chi_f) / de)


def test_twins_within_the_solver_accuracy_are_one_optimum():
    """Two starts whose chi-squares differ by less than the eigenvalue tolerance can move them are one
    optimum: the first start's is taken, whichever is lower by round-off."""
    from jointid.diagnosis.fitting import EIGEN_RTOL, best_fit, chi2_resolution

    n = 16
    rows = [(0, m + 1) for m in range(n)]
    J = np.ones((n, 1))
    r = np.full(n, np.sqrt(14.094 / n))
    a = _fit(r * np.sqrt(14.094003 / 14.094), J, rows, [0.002] * n)
    b = _fit(r * np.sqrt(14.0939423 / 14.094), J, rows, [0.002] * n)
    # sum |r_i| eig_rtol / sigma_i: 16 rows of |r| 0.94 at sigma 0.2 % move chi2 by about 7.5e-3
    assert chi2_resolution(a) == pytest.approx(np.sum(np.abs(a.ev.r)) * EIGEN_RTOL / 0.002)
    assert best_fit([a, b]) is a and best_fit([b, a]) is b
    far = _fit(r * np.sqrt(14.2 / 14.094), J, rows, [0.002] * n)
    assert best_fit([far, b]) is b


def test_a_parameter_the_data_barely_constrain_gets_an_open_interval_not_an_overflow():
    from jointid.diagnosis.results import log_interval

    lo, hi = log_interval(8e11, 0.1)
    assert lo == pytest.approx(8e11 * np.exp(-0.196)) and hi == pytest.approx(8e11 * np.exp(0.196))
    assert log_interval(8e11, 1e4) == (0.0, float("inf"))  # math.exp(19600) would raise OverflowError


def test_mode_correlation_is_the_mac_matrix_with_rows_without_a_mode_apart():
    a, b = np.array([1.0, 0.0, 0.0]), np.array([1.0, 1.0, 0.0])
    R = mode_correlation(np.column_stack([a, b, 2 * a, np.zeros(3)]))
    np.testing.assert_allclose(R[0], [1.0, 0.5, 1.0, 0.0])
    np.testing.assert_allclose(R[3], [0.0, 0.0, 0.0, 1.0])
    assert np.all(np.linalg.eigvalsh(R) > -1e-12)


def test_a_mesh_error_shared_by_a_mode_in_two_states_cancels_in_their_difference():
    """One mode measured in two states (rows 0, 1: the same model mode, MAC 1), noise s, known error k.
    Analytic: C = s^2 I + k^2 [[1, 1], [1, 1]], so the common part (e0 + e1)/2 has variance
    s^2/2 + k^2 and the difference e0 - e1 has 2 s^2: a between-state residual is judged at the noise
    alone, a common one at the noise plus the mesh error."""
    s, k = 0.001, 0.02
    R = np.ones((2, 2))
    diff, common = np.array([2.0, -2.0]), np.array([10.0, 10.0])  # residuals in units of s
    for r, expect in ((diff, (0.004 ** 2) / (2 * s ** 2)),
                      (common, 2 * (0.01 ** 2) / (2 * (s ** 2 / 2 + k ** 2)))):
        got = NO_MODEL_ERROR.chi2_total(r, s, np.full(2, k), R)
        assert got == pytest.approx(expect, rel=1e-9)
        A = NO_MODEL_ERROR.whitener(np.full(2, s), np.full(2, k), R)
        assert float((A @ r) @ (A @ r)) == pytest.approx(expect, rel=1e-9)
    # independent known errors would discount the difference as much as the common part
    assert NO_MODEL_ERROR.chi2_total(diff, s, np.full(2, k)) < 0.1 * NO_MODEL_ERROR.chi2_total(diff, s, np.full(2, k), R)


def test_the_moment_equation_with_correlated_known_errors():
    """sigma_m solves the weighted equation (identification/model_error.py) in the eigenbasis of
    S + D R D: checked against a direct evaluation there, and R = I gives the independent result."""
    rng = np.random.default_rng(3)
    n, s = 6, 0.002
    k = np.full(n, 0.01)
    shapes = rng.standard_normal((5, 3))
    P = np.hstack([shapes, shapes])  # three modes, each in two states
    R = mode_correlation(P)
    r = np.array([4.0, -3.0, 5.0, -4.0, 3.0, -5.0])  # differences between the states far above the noise
    me = estimate(r, s, 1, known_rel=k, known_corr=R)
    assert me.sigma_model_rel > 0
    C = ModelError(sigma_model_rel=me.sigma_model_rel).covariance(np.full(n, s), k, R)
    lam, Q = np.linalg.eigh(C)
    e2 = (Q.T @ (r * s)) ** 2
    assert float(np.sum(e2 / lam ** 2)) == pytest.approx((n - 1) / n * float(np.sum(1 / lam)), rel=1e-8)
    indep = estimate(r, s, 1, known_rel=k, known_corr=np.eye(n))
    assert indep.sigma_model_rel == pytest.approx(estimate(r, s, 1, known_rel=k).sigma_model_rel, rel=1e-9)
    assert indep.sigma_model_rel < me.sigma_model_rel


def test_a_known_part_of_each_rows_own_beside_the_shared_one():
    """known_budget: a shared part k (correlated by R) and an own part u per row.  Analytic: one mode in
    two states, k = 2 %, u = 0.3 % and 0.4 %: the difference of the two rows carries u0^2 + u1^2 of known
    variance, the mean (k^2 + (u0^2 + u1^2)/4)."""
    from jointid.identification.model_error import known_budget

    k, R = known_budget(np.array([0.02, 0.02]), np.ones((2, 2)), np.array([0.003, 0.004]))
    np.testing.assert_allclose(k, np.sqrt(0.02 ** 2 + np.array([0.003, 0.004]) ** 2))
    C = k[:, None] * R * k[None, :]
    assert float(np.array([1, -1]) @ C @ np.array([1, -1])) == pytest.approx(0.003 ** 2 + 0.004 ** 2, rel=1e-12)
    assert float(np.array([0.5, 0.5]) @ C @ np.array([0.5, 0.5])) == pytest.approx(
        0.02 ** 2 + (0.003 ** 2 + 0.004 ** 2) / 4, rel=1e-12)
    assert np.allclose(np.diag(R), 1.0) and np.all(np.linalg.eigvalsh(R) > -1e-12)
    k0, R0 = known_budget(np.zeros(3), np.eye(3), np.zeros(3))
    assert R0 is None and not k0.any()


def test_sized_starts_are_the_effect_at_half_and_its_nominal_size_unless_tried():
    """When every start of a refit ends at the null, the effect is started at typical sizes: t = 0.5 and
    1 (t is in units of the nominal), a start within 5 % of one already tried left out."""
    from jointid.diagnosis.effects import EFFECTS
    from jointid.diagnosis.starts import at_its_null, refit_starts, sized_starts
    from jointid.diagnosis.variants import EffectSpec

    edge = EffectSpec.candidate(EFFECTS["added_mass_edge"])  # 0..15 kg, nominal 2 kg: t = mass / 2 kg
    tried = refit_starts(edge, -0.3)  # a first-order estimate of the wrong sign: every start near the null
    assert max(tried) < 0.1
    assert sized_starts(edge, tried) == [0.5, 1.0]  # 1 kg and 2 kg
    assert sized_starts(edge, [0.51]) == [1.0]
    assert at_its_null(edge, 0.0) and at_its_null(edge, 0.0009) and not at_its_null(edge, 0.002)  # 4 g
    base = EffectSpec.candidate(EFFECTS["base_support"])  # compliance: t = 1e10 / k_foundation, null at t = 0
    assert at_its_null(base, 1e10 / 2e13) and not at_its_null(base, 1e10 / 2e11)
    assert sized_starts(base, []) == []  # a compliance's nominal is no typical size
