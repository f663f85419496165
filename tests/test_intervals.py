"""Reported 95 % intervals of the diagnosis are widened by max(1, sqrt(chi2/dof)) (Birge ratio),
as the identification's and the hypotheses' are: analytic references on a linear model."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from jointid.diagnosis.results import Evaluation, Fit


def _fit(r, J):
    r, J = np.asarray(r, float), np.asarray(J, float)
    ev = Evaluation(x=np.zeros(J.shape[1]), r=r, J=J, solutions=[], index=[], rows=[], f_model=[])
    return Fit(variant=SimpleNamespace(n_params=J.shape[1]), ev=ev, pairings=[])


def test_scale_is_the_root_of_chi2_per_degree_of_freedom():
    # six residuals, two parameters: chi2 = 25 over 4 degrees of freedom -> scale 2.5
    J = np.vstack([np.eye(2) * [2.0, 0.5], np.zeros((4, 2))])
    f = _fit([3.0, 4.0, 0, 0, 0, 0], J)
    assert f.chi2 == pytest.approx(25.0)
    assert f.interval_scale() == pytest.approx(2.5)
    # (J^T J)^-1 = diag(1/4, 4): the plain covariance, and the one every interval uses
    np.testing.assert_allclose(f.covariance(), np.diag([0.25, 4.0]), rtol=1e-12)
    np.testing.assert_allclose(f.scaled_covariance(), np.diag([0.25, 4.0]) * 6.25, rtol=1e-12)


def test_a_fit_within_the_noise_keeps_its_intervals():
    J = np.vstack([np.eye(2), np.zeros((4, 2))])
    f = _fit([0.5, -0.5, 0.5, 0.1, 0, 0], J)  # chi2 0.76 < 4 degrees of freedom
    assert f.interval_scale() == 1.0
    np.testing.assert_allclose(f.scaled_covariance(), f.covariance())


def test_parameters_chosen_outside_x_take_degrees_of_freedom():
    J = np.vstack([np.eye(2), np.zeros((4, 2))])
    f = _fit([3.0, 4.0, 0, 0, 0, 0], J)
    assert f.interval_scale(extra_params=1) == pytest.approx(math.sqrt(25.0 / 3.0))
    # never fewer than one degree of freedom
    assert f.interval_scale(extra_params=10) == pytest.approx(5.0)
