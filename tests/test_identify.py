"""Tests of jointid.identification.identify on a 3-DOF spring-mass chain with known stiffnesses.

Chain: ground -k1- m1 -k2- m2 -k3- m3, unit masses.  Frequencies from scipy.linalg.eigh.
"""

import json
import warnings

import numpy as np
import pytest
import scipy.linalg as sl

from jointid.identification import doe
from jointid.errors import NumericalWarning
from jointid.identification.identify import identify
from jointid.identification.surface import fit_surface

MASS = np.eye(3)  # kg
K3_FIXED = 1.0e6  # N/m, third spring when only two are identified


def chain_freqs(k):
    """Natural frequencies (Hz, ascending) of the chain for spring stiffnesses k (N/m)."""
    k1, k2 = k[0], k[1]
    k3 = k[2] if len(k) > 2 else K3_FIXED
    K = np.array([[k1 + k2, -k2, 0.0], [-k2, k2 + k3, -k3], [0.0, -k3, k3]])
    return np.sqrt(sl.eigh(K, MASS, eigvals_only=True)) / (2 * np.pi)


def chain_model(lower, upper):
    return lambda x: chain_freqs(doe.to_physical(x, lower, upper))


# moderately narrow DOE box (a factor 2 per stiffness) and a truth inside it, off centre
LO2, HI2 = np.array([7e5, 6e5]), np.array([1.4e6, 1.2e6])
K_TRUE2 = np.array([1.15e6, 0.85e6])
NAMES2 = ["k1_N_per_m", "k2_N_per_m"]


def test_noise_free_recovery_exact_model_three_springs():
    lo, hi = np.array([1e5, 1e5, 1e5]), np.array([1e7, 1e7, 1e7])
    k_true = np.array([2.0e6, 0.5e6, 1.3e6])
    model = chain_model(lo, hi)
    f_meas = chain_freqs(k_true)
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumericalWarning)  # nothing to warn about here
        r = identify(model, f_meas, lower=lo, upper=hi, names=["k1", "k2", "k3"], seed=1)
    np.testing.assert_allclose(r.theta, k_true, rtol=0.01)
    np.testing.assert_allclose(r.x_coded, doe.to_coded(k_true, lo, hi), atol=1e-6)
    assert r.cost < 1e-16 and np.abs(r.residual_pct).max() < 1e-6
    assert r.identifiable and r.weak_combination is None and r.on_bound == []
    assert 1 <= r.n_starts_agreeing <= r.n_starts == 16
    # intervals are asymmetric in physical units, symmetric in log10
    assert np.all(r.ci_lower < r.theta) and np.all(r.theta < r.ci_upper)
    np.testing.assert_allclose(np.log10(r.ci_upper) - np.log10(r.theta),
                               np.log10(r.theta) - np.log10(r.ci_lower), rtol=1e-9)
    assert np.all(r.ci_upper - r.theta > r.theta - r.ci_lower)
    # serialisable
    d = json.loads(json.dumps(r.to_dict()))
    assert d["names"] == ["k1", "k2", "k3"] and len(d["theta"]) == 3


def test_noise_free_recovery_with_quadratic_surface_on_ccf():
    model = chain_model(LO2, HI2)
    X = doe.design("ccf", 2, n_center=1)
    logF = np.log(np.array([model(x) for x in X]))
    s = fit_surface(X, logF)  # fit log(f), as recommended
    f_meas = chain_freqs(K_TRUE2)
    r = identify(lambda x: np.exp(s(x)), f_meas,
                 jacobian=lambda x: np.exp(s(x))[:, None] * s.jacobian(x),
                 lower=LO2, upper=HI2, names=NAMES2)
    np.testing.assert_allclose(r.theta, K_TRUE2, rtol=0.01)
    # and without the analytic Jacobian (finite differences) the same optimum
    r_fd = identify(lambda x: np.exp(s(x)), f_meas, lower=LO2, upper=HI2, names=NAMES2)
    np.testing.assert_allclose(r_fd.theta, r.theta, rtol=1e-6)


def test_uncertainty_matches_linear_theory():
    """cov = sigma^2 (J^T J)^-1 with J the Jacobian of relative residuals (independent check)."""
    model = chain_model(LO2, HI2)
    f_meas = chain_freqs(K_TRUE2)
    r = identify(model, f_meas, lower=LO2, upper=HI2, names=NAMES2, sigma_rel=0.02, n_starts=2)
    x = r.x_coded
    h = 1e-5
    Jrel = np.column_stack([(model(x + h * e) - model(x - h * e)) / (2 * h) for e in np.eye(2)])
    Jrel /= f_meas[:, None]
    cov = 0.02**2 * np.linalg.inv(Jrel.T @ Jrel)
    np.testing.assert_allclose(r.cov_coded, cov, rtol=1e-5)
    half = 0.5 * np.log10(HI2 / LO2)
    np.testing.assert_allclose(r.sd_log10, np.sqrt(np.diag(cov)) * half, rtol=1e-5)


def test_intervals_cover_truth_under_noise():
    model = chain_model(LO2, HI2)
    f_true = chain_freqs(K_TRUE2)
    rng = np.random.default_rng(20240611)
    n_rep, covered = 60, np.zeros(2)
    widths = []
    for _ in range(n_rep):
        f_meas = f_true * (1 + 0.005 * rng.standard_normal(f_true.size))
        r = identify(model, f_meas, lower=LO2, upper=HI2, names=NAMES2, sigma_rel=0.005,
                     n_starts=3)
        covered += (r.ci_lower <= K_TRUE2) & (K_TRUE2 <= r.ci_upper)
        widths.append(np.log10(r.ci_upper / r.ci_lower))
    coverage = covered / n_rep
    assert np.all(coverage >= 0.90), coverage
    # the intervals are informative, not trivially wide (less than a factor 1.5)
    assert np.max(widths) < np.log10(1.5)


def test_parameter_without_influence_is_flagged():
    lo, hi = np.append(LO2, 1e3), np.append(HI2, 1e5)
    names = NAMES2 + ["k_dummy_N_per_m"]
    model = lambda x: chain_freqs(doe.to_physical(x[:2], LO2, HI2))  # ignores x[2]
    with pytest.warns(NumericalWarning, match="k_dummy_N_per_m.*not identifiable"):
        r = identify(model, chain_freqs(K_TRUE2), lower=lo, upper=hi, names=names, n_starts=4)
    assert not r.identifiable
    assert r.condition_number > 1e3
    assert "k_dummy_N_per_m" in r.weak_combination
    assert "k1_N_per_m" not in r.weak_combination and "k2_N_per_m" not in r.weak_combination
    assert r.cov_singular
    assert r.ci_lower[2] == 0.0 and np.isinf(r.ci_upper[2])  # unbounded, not falsely tight
    np.testing.assert_allclose(r.theta[:2], K_TRUE2, rtol=0.01)  # the others still identified
    assert json.loads(json.dumps(r.to_dict()))["ci_upper"][2] is None


def test_product_only_dependence_names_the_combination():
    """Frequencies depending on k1*k2 only: log10 k1 - log10 k2 (direction) is undetermined."""
    lo, hi = np.array([1e5, 1e5]), np.array([1e7, 1e7])

    def model(x):
        k = doe.to_physical(x, lo, hi)
        return np.array([1.0, 2.0, 3.5]) * np.sqrt(np.sqrt(k[0] * k[1]))

    with pytest.warns(NumericalWarning, match="not identifiable"):
        r = identify(model, model(np.array([0.2, -0.1])), lower=lo, upper=hi, names=["ka", "kb"],
                     n_starts=3)
    assert r.weak_combination in ("0.71*ka - 0.71*kb (in log10)", "0.71*kb - 0.71*ka (in log10)")


def test_truth_outside_bounds_is_flagged_on_bound():
    model = chain_model(LO2, HI2)
    k_true = np.array([1.0e6, 1.6e6])  # k2 above its upper bound 1.2e6
    with pytest.warns(NumericalWarning, match=r"k2_N_per_m sits on its upper bound 1\.2e6.*"
                                              r"widen joints\.parameters\.k2_N_per_m bounds"):
        r = identify(model, chain_freqs(k_true), lower=LO2, upper=HI2, names=NAMES2, n_starts=4)
    assert r.on_bound == ["k2_N_per_m"]
    assert r.x_coded[1] == pytest.approx(1.0, abs=1e-3)
    assert r.cost > 1e-6  # the bounded fit cannot reproduce the data


def test_extra_residuals_and_weights_enter_the_objective():
    model = chain_model(LO2, HI2)
    f_meas = chain_freqs(K_TRUE2)
    x_target = doe.to_coded(np.array([1.0e6, 1.0e6]), LO2, HI2)
    # a heavy extra term pulling towards another point moves the optimum there
    r = identify(model, f_meas, lower=LO2, upper=HI2, names=NAMES2, n_starts=3,
                 extra=lambda x: 100.0 * (x - x_target))
    np.testing.assert_allclose(r.x_coded, x_target, atol=1e-3)
    assert r.residuals.size == 5 and r.jacobian.shape == (5, 2)
    # the extra residuals' Jacobian given (here exactly 100 I) gives the fit of central differences
    r_j = identify(model, f_meas, lower=LO2, upper=HI2, names=NAMES2, n_starts=3,
                   extra=lambda x: 100.0 * (x - x_target), extra_jacobian=lambda x: 100.0 * np.eye(2))
    np.testing.assert_allclose(r_j.x_coded, r.x_coded, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(r_j.jacobian[3:], 100.0 * np.eye(2), rtol=1e-12)
    # zero weight on mode 3: data from a different k-set in mode 3 only changes nothing
    f_bad = f_meas.copy()
    f_bad[2] *= 1.1
    r_w = identify(model, f_bad, weights=[1.0, 1.0, 0.0], lower=LO2, upper=HI2, names=NAMES2,
                   n_starts=3)
    np.testing.assert_allclose(r_w.theta, K_TRUE2, rtol=1e-6)
    assert r_w.residual_pct[2] == pytest.approx(100 * (1 / 1.1 - 1), rel=1e-6)
