"""The likelihood with model error (jointid.identification.model_error): analytic references."""

import math

import numpy as np
import pytest

from jointid.identification import model_error as M


def test_uniform_noise_gives_quasi_likelihood_c_hat():
    """One stated sigma for all rows: sigma^2 + sigma_m^2 = c_hat sigma^2, QAICc = chi2 / c_hat + penalty."""
    rng = np.random.default_rng(1)
    r = rng.normal(size=14) * 3.0
    me = M.estimate(r, 0.01, 3)
    c_hat = float(r @ r) / 11
    assert me.c_hat == pytest.approx(c_hat)
    assert me.sigma_model_rel == pytest.approx(0.01 * math.sqrt(c_hat - 1), rel=1e-9)
    assert me.inflation == pytest.approx(c_hat, rel=1e-9)
    other = rng.normal(size=14) * 4.0
    chi2_m = me.chi2_total(other, 0.01)
    assert chi2_m == pytest.approx(float(other @ other) / c_hat, rel=1e-9)
    assert M.qaicc(chi2_m, 14, 4) == pytest.approx(chi2_m + 8 + 2 * 4 * 5 / 9)


def test_within_noise_changes_nothing():
    r = np.array([0.5, -1.0, 0.8, 0.2, -0.3, 0.1])
    me = M.estimate(r, 0.02, 2)
    assert me.sigma_model_rel == 0.0 and not me.above_noise
    assert me.chi2_total(r, 0.02) == pytest.approx(float(r @ r))
    assert np.all(me.row_weights(np.full(6, 0.02)) == 1.0)


def test_known_part_reduces_the_model_error():
    """With a known part, the weighted equation sum w^2 e^2 = (n - k)/n sum w, w = 1/(s^2 + k^2 + sm^2),
    solved exactly (module doc)."""
    s = np.array([0.01, 0.01, 0.02, 0.02, 0.01])
    e = np.array([0.05, -0.04, 0.03, -0.06, 0.02])
    k = np.full(5, 0.01)
    me = M.estimate(e / s, s, 1, known_rel=k)
    w = 1.0 / (s ** 2 + k ** 2 + me.sigma_model_rel ** 2)
    assert float(np.sum(w * w * e ** 2)) == pytest.approx(4.0 / 5.0 * float(np.sum(w)), rel=1e-9)
    without = M.estimate(e / s, s, 1)
    assert me.sigma_model_rel < without.sigma_model_rel


def test_known_part_that_dominates_some_rows_leaves_the_others_to_judge():
    """Three rows carry a known error 20x their noise, three none; the residuals are 2x the noise
    everywhere.  The weighted equation takes sigma_m from the rows that can show it (about
    sqrt(4 - 1) s, as with those rows alone); the moment equation would count the dominated rows as
    three degrees of freedom they do not carry and find less."""
    n, s = 6, 0.001
    r = np.array([2.0, -2.0, 2.0, -2.0, 2.0, -2.0])
    k = np.array([0.02, 0.02, 0.02, 0.0, 0.0, 0.0])
    me = M.estimate(r, s, 0, known_rel=k)
    assert me.sigma_model_rel == pytest.approx(s * math.sqrt(3.0), rel=0.02)
    moment = M.estimate(r[3:], s, 0).sigma_model_rel  # the free rows alone: the same answer
    assert me.sigma_model_rel == pytest.approx(moment, rel=0.02)


def test_weights_and_support():
    w = M.akaike_weights([10.0, 12.0, np.inf])
    assert w == pytest.approx([1 / (1 + math.exp(-1)), math.exp(-1) / (1 + math.exp(-1)), 0.0])
    assert M.support_text(-12) == "strongly"
    assert M.support_text(-5) == "moderately"
    assert M.support_text(-3.9) == "not" and M.support_text(2) == "not" and M.support_text(np.nan) == "not"


def test_sentence_states_the_numbers():
    me = M.estimate(np.full(10, 4.0), 0.01, 2, reference="the baseline")
    assert me.c_hat == pytest.approx(20.0)
    txt = me.sentence()
    assert "4.4 % per mode" in txt and "4.4 times" in txt and "the baseline" in txt


def test_from_chi2_equals_the_general_estimate_for_one_sigma():
    r = np.array([3.0, -2.0, 4.0, 1.0, -3.5, 2.5, 0.5])
    a = M.from_chi2(float(r @ r), 5, 0.01)
    b = M.estimate(r, 0.01, 2)
    assert a.sigma_model_rel == pytest.approx(b.sigma_model_rel, rel=1e-9) and a.c_hat == pytest.approx(b.c_hat)
    assert M.from_chi2(3.0, 5, 0.01).sigma_model_rel == 0.0
