"""The rules that tell one optimum from two (jointid.diagnosis.starts.chi2_tie,
jointid.diagnosis.loop.outside_interval): analytic references on stand-in fits."""

from types import SimpleNamespace

import numpy as np


def test_a_tie_is_the_larger_of_the_relative_tolerance_and_the_solvers_resolution():
    from jointid.diagnosis.starts import EIGEN_RTOL, TIE_RTOL, chi2_tie

    no_ev = SimpleNamespace(chi2=500.0, ev=None)
    assert np.isclose(chi2_tie(no_ev), TIE_RTOL * 500.0 + 1e-9)
    assert np.isclose(chi2_tie(no_ev, low=2000.0), TIE_RTOL * 2000.0 + 1e-9)
    # the resolution: sum |r_i| eig_rtol / sigma_i over the frequency rows; the shape row (mode -1) is left out
    ev = SimpleNamespace(r=np.array([2.0, -2.0, 2.0, 5.0]), sigma=np.full(4, 0.01),
                         rows=[(0, 0), (0, 1), (0, 2), (0, -1)])
    with_ev = SimpleNamespace(chi2=12.0, ev=ev)
    assert np.isclose(chi2_tie(with_ev), 6.0 * EIGEN_RTOL / 0.01 + 1e-9)  # 6e-4, above 1e-6 x 12


def test_another_basin_lies_outside_the_95_percent_interval_of_some_parameter():
    from jointid.diagnosis.loop import outside_interval

    fit = SimpleNamespace(x=np.array([27.0, 26.0, 0.3]), scaled_covariance=lambda: np.diag([0.01, 0.04, 1.0]))
    # standard errors 0.1, 0.2, 1: the 95 % half-widths 0.196, 0.392, 1.96
    assert not outside_interval(fit, [27.19, 25.61])
    assert outside_interval(fit, [27.2, 26.0])
    assert outside_interval(fit, [27.0, 26.4])
    assert not outside_interval(fit, [27.0, 26.0, 2.2])  # within the third's 1.96
    assert outside_interval(fit, [27.0, 26.0, 2.3])
