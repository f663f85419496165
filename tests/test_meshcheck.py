"""First-order re-identification of the mesh check against exact least squares."""

import numpy as np
import pytest

from jointid.identification.meshcheck import error_budget, first_order_shift
from jointid.identification.record import IdentificationRecord
from jointid.identification.polish import log_jacobian


def test_shift_equals_the_refit_of_a_linear_model():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(6, 3))
    w = rng.uniform(0.5, 2.0, 6)
    y_true = rng.normal(size=3)
    meas = J @ y_true + 0.01 * rng.normal(size=6)  # ln f_meas, not exactly reachable
    def fit(offset):  # weighted least squares of ln f = J y + offset against meas
        A = J * np.sqrt(w)[:, None]
        return np.linalg.lstsq(A, np.sqrt(w) * (meas - offset), rcond=None)[0]
    base = fit(np.zeros(6))
    dlnf = 0.003 * rng.normal(size=6)
    assert first_order_shift(J, dlnf, w) == pytest.approx(fit(dlnf) - base, abs=1e-12)


def test_uniform_softening_of_a_one_parameter_model():
    # f ~ sqrt(k): a model 1 % too stiff in frequency needs k 2 % lower... on a mesh that is 1 % softer,
    # the refit k rises by about 2 % (d ln f / d log10 k = ln(10) / 2)
    J = np.full((4, 1), np.log(10) / 2)
    d = first_order_shift(J, np.full(4, np.log(0.99)))
    assert 100 * (10 ** d[0] - 1) == pytest.approx(100 * (1 / 0.99**2 - 1), rel=1e-12)


def test_log_jacobian_of_a_spring_mass():
    """One mass on a spring: lambda = k/m, d ln f / d log10 k = ln(10)/2."""
    import scipy.sparse as sp

    m, k = 2.0, 5.0e6
    phi = np.array([[1 / np.sqrt(m)]])
    J = log_jacobian({"K_a": sp.csr_matrix([[1.0]])}, phi, np.array([k / m]), [{"K_a": 1.0}], np.array([k]))
    assert J[0, 0] == pytest.approx(np.log(10) / 2, rel=1e-12)


def test_error_budget_holds_the_mesh_error_against_a_third_of_the_total_uncertainty():
    # noise 1 %, model error sqrt(15) %: total 4 %, a third of it 1.333 %
    par = IdentificationRecord({}, frequency_uncertainty_pct=1.0, model_error={"sigma_model_pct": 15 ** 0.5})
    b = error_budget([0.5, -1.2, np.nan], par, 1 / 3)
    assert b["uncertainty_pct"] == pytest.approx(4.0)
    assert b["budget_pct"] == pytest.approx(4.0 / 3)
    assert b["max_error_pct"] == pytest.approx(1.2) and b["worst_mode"] == 2 and b["within"]
    # the same mesh against the noise alone (an exact model): 1.2 % > 0.333 %
    b = error_budget([0.5, -1.2, np.nan], IdentificationRecord({}, frequency_uncertainty_pct=1.0), 1 / 3)
    assert not b["within"] and b["budget_pct"] == pytest.approx(1 / 3)
    assert "above it" in b["sentence"]
    assert "part of a uniform refinement" not in b["sentence"]  # every axis halved (error_budget's default)
    # the thickness alone (the mesh check's default): the sentence says a uniform refinement finds more
    thin = error_budget([0.5, -1.2, np.nan], par, 1 / 3, ("thickness",))["sentence"]
    assert "with the thickness cells halved: part of a uniform refinement's error, which is larger" in thin
    assert "part of a uniform" not in error_budget([0.5], par, 1 / 3, ("plan", "thickness"))["sentence"]
    # nothing followed: not within
    assert not error_budget([np.nan], par, 1 / 3)["within"]


def test_optimum_modes_round_trip_and_refuse_other_parameters(tmp_path):
    from jointid.errors import ModelError
    from jointid.identification.optimum_modes import OptimumModes

    at = OptimumModes(("k_normal_N_per_m3", "k_lateral_N_per_m3"), np.array([1.2e12, 3.4e11]),
                      np.array([100.0, 250.5, 400.25]), np.arange(12.0).reshape(4, 3), np.arange(6.0).reshape(3, 2),
                      5000)
    path = tmp_path / "optimum_modes.npz"
    at.write(path)
    back = OptimumModes.read(path)
    assert back.names == at.names and back.n_dofs == 5000
    for a, b in ((at.theta_N_per_m3, back.theta_N_per_m3), (at.freqs_Hz, back.freqs_Hz), (at.shapes, back.shapes),
                 (at.dlnf_dlog10theta, back.dlnf_dlog10theta)):
        assert np.array_equal(a, b)
    back.check_parameters(at.names, [1.2e12, 3.4e11], path)  # the same parameters: accepted
    with pytest.raises(ModelError, match="other joint parameters"):
        back.check_parameters(at.names, [1.2e12, 3.5e11], path)
    with pytest.raises(ModelError, match="rebuild them"):
        back.check_parameters(at.names[::-1], [3.4e11, 1.2e12], path)
