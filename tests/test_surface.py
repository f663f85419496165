"""Tests of jointid.identification.surface: exact recovery, diagnostics, serialisation, Jacobians."""

import json

import numpy as np
import pytest

from jointid.identification import doe
from jointid.errors import ConfigError
from jointid.identification.surface import Surface, fit_surface, quadratic_basis
from jointid.identification.surface_checks import diagnostics, verification_errors


def _known_quadratic(X):
    """Two responses: an arbitrary full quadratic in 3 factors and a linear one."""
    x0, x1, x2 = X.T
    y0 = 3.0 + 0.5 * x0 - 1.2 * x1 + 0.3 * x2 + 0.7 * x0 * x1 - 0.2 * x0 * x2 + 0.1 * x1 * x2 \
        + 0.9 * x0**2 - 0.4 * x1**2 + 0.25 * x2**2
    y1 = 10.0 + 2.0 * x0 - x2
    return np.column_stack([y0, y1])


def test_known_quadratic_recovered_exactly():
    X = doe.design("ccf", 3, n_center=2)
    Y = _known_quadratic(X)
    s = fit_surface(X, Y, response_names=["f1_Hz", "f2_Hz"])
    expected = np.array([3.0, 0.5, -1.2, 0.3, 0.7, -0.2, 0.1, 0.9, -0.4, 0.25])
    np.testing.assert_allclose(s.coef[:, 0], expected, atol=1e-12)
    d = diagnostics(s, X, Y)
    assert list(d.index) == ["f1_Hz", "f2_Hz"]
    np.testing.assert_allclose(d["r2"], 1.0, atol=1e-12)
    np.testing.assert_allclose(d["r2_adj"], 1.0, atol=1e-12)
    np.testing.assert_allclose(d["r2_pred"], 1.0, atol=1e-12)
    assert d["rmse"].max() < 1e-12
    assert (d["n_points"] == 16).all() and (d["n_terms"] == 10).all()
    # and it predicts at new points
    V = doe.verification_points(7, 3, seed=1)
    np.testing.assert_allclose(s.predict(V), _known_quadratic(V), atol=1e-12)


def test_noisy_data_predicted_r2_below_r2():
    X = doe.design("lhs", 2, n_samples=30, seed=3)
    rng = np.random.default_rng(0)
    y = 1.0 + X[:, 0] - 0.5 * X[:, 1] ** 2 + 0.2 * rng.standard_normal(len(X))
    s = fit_surface(X, y)
    d = diagnostics(s, X, y).iloc[0]
    assert 0.5 < d["r2"] < 1.0
    assert d["r2_pred"] < d["r2_adj"] < d["r2"]
    # r2 and rmse agree with their definitions
    e = y - s.predict(X)[:, 0]
    assert d["rmse"] == pytest.approx(np.sqrt(np.mean(e**2)), rel=1e-12)
    assert d["r2"] == pytest.approx(1 - np.sum(e**2) / np.sum((y - y.mean()) ** 2), rel=1e-12)


def test_press_matches_explicit_leave_one_out():
    X = doe.design("lhs", 2, n_samples=14, seed=5)
    y = np.exp(0.8 * X[:, 0]) * (1 + 0.3 * X[:, 1] ** 3)
    s = fit_surface(X, y)
    loo = []
    for i in range(len(X)):
        keep = np.arange(len(X)) != i
        loo.append(fit_surface(X[keep], y[keep]).predict(X[i])[0, 0])
    press = np.sum((y - np.array(loo)) ** 2)
    r2_pred = 1 - press / np.sum((y - y.mean()) ** 2)
    assert diagnostics(s, X, y)["r2_pred"].iloc[0] == pytest.approx(r2_pred, rel=1e-10)


def test_saturated_design_gives_nan_not_crash():
    # 4 corners + 2 axial points: 6 points for 6 terms, every leverage is 1
    X = np.vstack([doe.design("ccf", 2, n_center=0)[:4], [[-1.0, 0.0], [0.0, -1.0]]])
    y = 1 + X[:, 0] + X[:, 1] ** 2
    d = diagnostics(fit_surface(X, y), X, y).iloc[0]
    assert d["n_points"] == d["n_terms"] == 6
    assert np.isnan(d["r2_adj"]) and np.isnan(d["r2_pred"])
    assert d["r2"] == pytest.approx(1.0)


def test_too_few_points_is_config_error():
    with pytest.raises(ConfigError, match="needs 10"):
        fit_surface(np.zeros((5, 3)), np.zeros(5))


@pytest.mark.parametrize("kind", ["quadratic", "rbf"])
def test_json_round_trip_predicts_identically(kind):
    X = doe.design("ccf", 3, n_center=1)
    Y = np.column_stack([np.log(100 + 30 * X[:, 0] + 10 * np.sin(X[:, 1])), X[:, 2] ** 3])
    s = fit_surface(X, Y, kind, response_names=["log_f1", "y"])
    s2 = Surface.from_dict(json.loads(json.dumps(s.to_dict())))
    assert type(s2) is type(s) and s2.response_names == ["log_f1", "y"]
    V = doe.verification_points(9, 3, seed=2)
    np.testing.assert_array_equal(s2.predict(V), s.predict(V))


def test_rbf_interpolates_training_points_and_loo_is_honest():
    X = doe.design("lhs", 2, n_samples=25, seed=1)
    Y = np.column_stack([np.sin(2 * X[:, 0]) * np.cos(X[:, 1]), np.exp(X[:, 1])])
    s = fit_surface(X, Y, "rbf")
    np.testing.assert_allclose(s.predict(X), Y, atol=1e-9)
    d = diagnostics(s, X, Y)
    np.testing.assert_allclose(d["r2"], 1.0, atol=1e-12)
    assert d["r2_adj"].isna().all()
    assert (d["r2_pred"] < 1.0).all() and (d["r2_pred"] > 0.9).all()
    # 1-D call form used by identify
    np.testing.assert_allclose(s(X[3]), Y[3], atol=1e-9)


@pytest.mark.parametrize("kind", ["quadratic", "rbf"])
def test_jacobian_matches_finite_differences(kind):
    X = doe.design("ccf", 3, n_center=1)
    Y = np.column_stack([np.exp(0.4 * X[:, 0] - 0.3 * X[:, 1] * X[:, 2]), X[:, 0] * X[:, 2]])
    s = fit_surface(X, Y, kind)
    x = np.array([0.3, -0.45, 0.6])
    h = 1e-5
    fd = np.column_stack([(s(x + h * e) - s(x - h * e)) / (2 * h) for e in np.eye(3)])
    J = s.jacobian(x)
    assert J.shape == (2, 3)
    np.testing.assert_allclose(J, fd, rtol=1e-6, atol=1e-8)


def test_quadratic_jacobian_is_analytic_value():
    # y = 2 x0 x1 + 3 x1^2 -> dy/dx = (2 x1, 2 x0 + 6 x1)
    X = doe.design("ccf", 2)
    s = fit_surface(X, 2 * X[:, 0] * X[:, 1] + 3 * X[:, 1] ** 2)
    np.testing.assert_allclose(s.jacobian([0.5, -0.25]), [[-0.5, 1.0 - 1.5]], atol=1e-12)


def test_quadratic_basis_order():
    A = quadratic_basis(np.array([[2.0, 3.0, 5.0]]))
    np.testing.assert_array_equal(A[0], [1, 2, 3, 5, 6, 10, 15, 4, 9, 25])


@pytest.mark.parametrize("k", [1, 2, 4])
def test_quadratic_basis_and_its_gradient_by_hand(k):
    """Columns 1, x_i, x_i x_j (i < j), x_i^2 of several points, and their derivative, written out."""
    from jointid.identification.surface import _quadratic_basis_gradient

    X = np.random.default_rng(k).uniform(-1, 1, (3, k))
    for x, row in zip(X, quadratic_basis(X)):
        cross = [x[i] * x[j] for i in range(k) for j in range(i + 1, k)]
        np.testing.assert_array_equal(row, [1.0, *x, *cross, *(x ** 2)])
        G = np.zeros((row.size, k))
        G[1:1 + k] = np.eye(k)
        t = 1 + k
        for i in range(k):
            for j in range(i + 1, k):
                G[t, i], G[t, j] = x[j], x[i]
                t += 1
        G[t:] = 2.0 * np.diag(x)
        np.testing.assert_array_equal(_quadratic_basis_gradient(x), G)


def test_verification_errors_relative():
    X = doe.design("ccf", 2)
    s = fit_surface(X, 100 + 10 * X[:, 0])
    V = np.array([[0.2, 0.1], [-0.5, 0.3]])
    ref = 100 + 10 * V[:, 0] + np.array([1.0, -2.0])  # surface is off by -1 and +2
    e = verification_errors(s, V, ref).iloc[0]
    assert e["max_abs_err"] == pytest.approx(2.0)
    assert e["max_rel_err_pct"] == pytest.approx(100 * 2.0 / 93.0)
