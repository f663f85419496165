"""Leave-one-mode-out prediction of the diagnosis's pairs (jointid.diagnosis.predictive).

Analytic reference: for a linear Gaussian model the score of a group of rows must equal -2 log of the
predictive density of a least-squares refit without that group (mean and parameter uncertainty).
Known truth: data drawn from one effect plus noise, a second candidate that sees one mode alone fits
better and is not confirmed; a second effect that is in the data and seen by several modes is
confirmed."""

from types import SimpleNamespace

import numpy as np
import pytest

from jointid.diagnosis.judging import parsimonious_order
from jointid.diagnosis.predictive import check_pairs, leave_one_mode_out, prediction_gain
from jointid.diagnosis.results import Evaluation, Fit
from jointid.identification.model_error import ModelError

SIGMA = 0.002  # relative frequency noise of every row


def _fit(J: np.ndarray, y: np.ndarray, rows: list) -> Fit:
    """The least-squares fit of ``y ~ J x`` (rows in units of their noise) as a diagnosis Fit."""
    x = np.linalg.lstsq(J, y, rcond=None)[0]
    ev = Evaluation(x=x, r=J @ x - y, J=J, solutions=[], index=[], rows=rows, f_model=[],
                    sigma=np.full(len(y), SIGMA))
    return Fit(SimpleNamespace(n_params=J.shape[1]), ev, [])


def _rows(n_modes: int, n_states: int = 2) -> list:
    return [(s, m) for s in range(n_states) for m in range(1, n_modes + 1)]


ME = ModelError(sigma_noise_rel=SIGMA)


def test_the_score_is_the_predictive_density_of_the_refit_without_the_mode():
    rng = np.random.default_rng(3)
    rows = _rows(6)
    J = rng.standard_normal((len(rows), 3))
    y = J @ np.array([1.0, -2.0, 0.5]) + rng.standard_normal(len(rows))
    got = leave_one_mode_out(_fit(J, y, rows), None, ME)
    for mode in range(1, 7):  # y_g given the rest: mean J_g x_(-g), covariance I + J_g (J_-g^T J_-g)^-1 J_g^T
        out = np.array([m == mode for _, m in rows])
        x = np.linalg.lstsq(J[~out], y[~out], rcond=None)[0]
        e = J[out] @ x - y[out]
        V = np.eye(int(out.sum())) + J[out] @ np.linalg.inv(J[~out].T @ J[~out]) @ J[out].T
        assert got[mode] == pytest.approx(float(e @ np.linalg.solve(V, e)) + np.linalg.slogdet(V)[1], rel=1e-9)


def test_an_effect_seen_by_one_mode_is_not_confirmed_and_one_seen_by_several_is():
    rng = np.random.default_rng(11)
    rows = _rows(6)
    n = len(rows)
    joints = rng.standard_normal((n, 2))
    true_effect = rng.standard_normal((n, 1))  # in the data, seen by every mode
    one_mode = np.array([[1.0 if m == 1 else 0.0] for _, m in rows])  # sees mode 1 alone
    y = joints @ np.array([1.0, 0.5]) + 3.0 * true_effect[:, 0] + rng.standard_normal(n)
    single = _fit(np.hstack([joints, true_effect]), y, rows)
    spurious_pair = _fit(np.hstack([joints, true_effect, one_mode]), y, rows)
    assert spurious_pair.chi2 < single.chi2  # it always fits better ...
    assert prediction_gain(spurious_pair, single, None, ME)[0] == np.inf  # ... and cannot predict mode 1
    # an effect in the data, against the joints alone: it predicts every left-out mode better
    delta, se = prediction_gain(single, _fit(joints, y, rows), None, ME)
    assert delta < -2 * se < 0
    # the rows of combinations.csv: the spurious pair names mode 1; the true effect on top of the other
    # single (a pair whose second effect is in the data) predicts better than that single
    fits = {"+a": single, "+b": _fit(np.hstack([joints, one_mode]), y, rows), "+a+b": spurious_pair}
    rows_out = [{"effects": "a+b"}]
    check_pairs(rows_out, fits, None, ME)
    r = rows_out[0]
    assert r["predicts"] is False and r["prediction_vs"] == "a" and r["prediction_worst_mode"] == 1
    fits = {"+b": fits["+b"], "+a+b": spurious_pair}  # only b refitted: a+b against b alone
    rows_out = [{"effects": "a+b"}]
    check_pairs(rows_out, fits, None, ME)
    assert rows_out[0]["predicts"] is True and rows_out[0]["prediction_delta"] < 0


def test_an_unconfirmed_pair_yields_to_its_single_beyond_the_tie():
    cands = [(-1210.0, "a+b"), (-1200.0, "a"), (-30.0, "b")]
    assert parsimonious_order(cands, 4.0)[0] == "a+b"  # 10 apart: outside the tie window
    assert parsimonious_order(cands, 4.0, no_gain=["a+b"])[0] == "a"
    assert parsimonious_order(cands, 4.0, no_gain=["b+a"])[0] == "a"  # either order of the pair


def test_the_verdict_says_why_a_better_fitting_pair_yields():
    import pandas as pd

    from jointid.diagnosis.verdict import Findings, unconfirmed_text

    combos = pd.DataFrame([{"effects": "em_preload+feed_stiffness", "delta_qaicc": -1210.3, "predicts": False,
                            "prediction_delta": np.inf, "prediction_se": np.inf, "prediction_vs": "em_preload",
                            "prediction_worst_mode": 1},
                           {"effects": "em_preload+rail_fixing", "delta_qaicc": -1196.0, "predicts": False,
                            "prediction_delta": 2.4, "prediction_se": 0.9, "prediction_vs": "em_preload",
                            "prediction_worst_mode": 6, "prediction_worst_pair": 5.2,
                            "prediction_worst_single": 4.3}])
    f = Findings(current=None, ranking=pd.DataFrame(), alpha=0.05, combinations=combos)
    sup = pd.DataFrame({"name": ["em_preload"], "delta_qaicc": [-1200.7]})
    txt = unconfirmed_text(f, sup, "em_preload")
    assert "em_preload + feed_stiffness fits better (ΔQAICc -1210.3)" in txt
    assert "with mode 1 left out, feed_stiffness's parameter is free" in txt
    assert "rail_fixing" not in txt  # it does not fit better than the lead: nothing to explain
