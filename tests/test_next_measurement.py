"""The measurement that would narrow the reconstruction (jointid.reconstruction.next_measurement): the
expected-gain arithmetic on analytic toys (three hypotheses with known predictions), no FE."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from jointid.reconstruction.next_measurement import (ProposalOptions, ScalarCandidate, ShapePairCandidate, expected_gain,
                                                next_measurement_markdown, propose)
from jointid.diagnosis.shape_proposal import pair_chi2
from jointid.identification.model_error import akaike_weights

NAMES = ["A", "B", "C"]
Q = np.array([0.0, 1.0, 2.0])  # QAICc: all three within 4 of the best
K_LAT = np.array([1e12, 2e12, 4e12])  # x4 today


def test_noise_free_gain_of_a_scalar_measurement_is_the_hand_computed_one():
    # weights 10, 10.1, 12 kg at 1 %: A and B cannot be told apart (chi2 ~ 1), C stands out (chi2 > 250)
    cand = ScalarCandidate("weight", "weight", "", "kg", 0.01, {"A": 10.0, "B": 10.1, "C": 12.0})
    w = akaike_weights(Q)
    g = expected_gain(cand, NAMES, Q, w, {"k": K_LAT}, n_draws=0)
    # truth A: chi2 = (y_A - y_h)^2 / (0.01 y_A)^2 -> [0, 1, 400]; QAICc [0, 2, 402]: A and B stay (x2)
    # truth B: [(0.1/0.101)^2, 0, (1.9/0.101)^2]; QAICc [0.98, 1, 356]: A and B stay (x2)
    # truth C: [(2/0.12)^2, (1.9/0.12)^2, 0]; QAICc [278, 252, 2]: C alone (x1)
    chi_a = np.array([0.0, 1.0, 400.0])
    chi_b = np.array([(0.1 / 0.101) ** 2, 0.0, (1.9 / 0.101) ** 2])
    chi_c = np.array([(2 / 0.12) ** 2, (1.9 / 0.12) ** 2, 0.0])
    np.testing.assert_allclose(cand.chi2("A", NAMES, np.zeros(1))[0], chi_a)
    np.testing.assert_allclose(cand.chi2("B", NAMES, np.zeros(1))[0], chi_b)
    np.testing.assert_allclose(cand.chi2("C", NAMES, np.zeros(1))[0], chi_c)
    wn = w / w.sum()
    assert g["ratio_before"]["k"] == pytest.approx(4.0)
    assert g["ratio_after"]["k"] == pytest.approx(2 * wn[0] + 2 * wn[1] + 1 * wn[2])
    assert g["n_left"] == pytest.approx(2 * wn[0] + 2 * wn[1] + 1 * wn[2])
    assert g["truth_kept"] == pytest.approx(1.0)
    assert g["min_delta_chi2"] == pytest.approx((0.1 / 0.101) ** 2)


def test_a_measurement_that_no_hypothesis_predicts_differently_gains_nothing():
    cand = ScalarCandidate("same", "weight", "", "kg", 0.02, {"A": 5.0, "B": 5.0, "C": 5.0})
    g = expected_gain(cand, NAMES, Q, akaike_weights(Q), {"k": K_LAT}, n_draws=200,
                      rng=np.random.default_rng(1))
    assert g["ratio_after"]["k"] == pytest.approx(4.0)
    assert g["n_left"] == pytest.approx(3.0)
    assert g["min_delta_chi2"] == 0.0


def test_noise_draws_of_a_decisive_measurement_keep_only_the_truth():
    # predictions 100 sigma apart: every draw keeps the truth alone
    cand = ScalarCandidate("stiff", "static stiffness", "s", "N/m", 0.01, {"A": 1.0, "B": 2.0, "C": 4.0})
    g = expected_gain(cand, NAMES, Q, akaike_weights(Q), {"k": K_LAT}, n_draws=300,
                      rng=np.random.default_rng(2))
    assert g["ratio_after"]["k"] == pytest.approx(1.0)
    assert g["n_left"] == pytest.approx(1.0)
    assert g["truth_kept"] == pytest.approx(1.0)


def test_noise_draws_average_the_survivors_of_a_borderline_measurement():
    # two hypotheses of equal QAICc, predictions 2 sigma apart (sigma from the truth's value)
    from scipy.stats import norm

    cand = ScalarCandidate("x", "weight", "", "kg", 0.1, {"A": 1.0, "B": 1.2})
    q = np.zeros(2)
    g = expected_gain(cand, ["A", "B"], q, akaike_weights(q), {"k": np.array([1.0, 3.0])}, n_draws=40000,
                      rng=np.random.default_rng(3))
    # of two hypotheses the second is kept while the first holds less than 95 % of the weight,
    # 1 / (1 + exp(-d / 2)) < 0.95, that is d < 2 ln 19 = 5.89 (past the delta of 4)
    t = 2 * np.log(19.0)
    # truth A (sigma 0.1, e the noise): chi2_A = e^2, chi2_B = (e - 2)^2; B kept when 4 - 4e < t,
    # A kept when 4e - 4 < t
    kept_a = (norm.cdf((4 + t) / 4), norm.sf((4 - t) / 4))
    both_a = kept_a[0] + kept_a[1] - 1
    # truth B (sigma 0.12): chi2_B = e^2, chi2_A = (e + a)^2, a = 0.2 / 0.12; A kept when 2ae + a^2 < t,
    # B kept when -2ae - a^2 < t
    a = 0.2 / 0.12
    hi, lo = (t - a * a) / (2 * a), -(t + a * a) / (2 * a)
    kept_b = (norm.cdf(hi), norm.sf(lo))
    both_b = norm.cdf(hi) - norm.cdf(lo)
    assert g["n_left"] == pytest.approx(0.5 * (sum(kept_a) + sum(kept_b)), abs=0.02)
    assert g["truth_kept"] == pytest.approx(0.5 * (kept_a[0] + kept_b[1]), abs=0.01)
    assert g["ratio_after"]["k"] == pytest.approx(0.5 * (1 + 2 * both_a) + 0.5 * (1 + 2 * both_b), abs=0.03)
    # noise-free, B at 1.25: from truth A B's chi2 is 6.25 (out), from truth B A's is (0.25 / 0.125)^2 = 4 (kept)
    cand0 = ScalarCandidate("x", "weight", "", "kg", 0.1, {"A": 1.0, "B": 1.25})
    g0 = expected_gain(cand0, ["A", "B"], q, akaike_weights(q), {"k": np.array([1.0, 3.0])}, n_draws=0)
    assert g0["n_left"] == pytest.approx(1.5) and g0["ratio_after"]["k"] == pytest.approx(2.0)


def test_the_shape_pair_candidate_agrees_with_the_diagnosis_pair_chi2():
    rng = np.random.default_rng(4)
    shapes = {n: rng.standard_normal((6, 3)) for n in NAMES}
    shapes = {n: s / np.sqrt(np.mean(s ** 2, axis=0)) for n, s in shapes.items()}
    i, j = 1, 4
    cand = ShapePairCandidate("pair", "shape", "s", "-", 0.05, {n: s[[i, j]] for n, s in shapes.items()})
    for g in NAMES:
        got = cand.chi2(g, NAMES, np.zeros((1, 2, 3)))[0]
        want = [pair_chi2(shapes[g], shapes[h], 0.05)[i, j] for h in NAMES]
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12)


def test_a_shape_pair_prediction_near_a_node_reads_as_displacements_not_a_ratio():
    """A DOF at a node of a mode: its ratio would run to ~1e5 (seen on the paper's data); the prediction gives
    each DOF's displacement in units of the mode's RMS, as the shapes hold it."""
    vals = {"a": np.array([[1.83, -0.40], [2e-5, 1.10]]), "b": np.array([[1.79, -0.52], [-3e-3, 0.98]])}
    text = ShapePairCandidate("pair", "shape", "s", "-", 0.05, vals).predictions_text(["a", "b"])
    assert text == "a [+1.83 +0.00, -0.40 +1.10]; b [+1.79 -0.00, -0.52 +0.98]"


def _record(k_lat, mass, k_static, q, shapes=None):
    return {"parameters": [{"parameter": "k_normal_N_per_m3", "value": 1e12},
                           {"parameter": "k_lateral_N_per_m3", "value": k_lat},
                           {"parameter": "em_preload.beta", "value": 0.3}],
            "predictions": {"moving_mass_kg": mass, "drive_point": "T05", "probe_labels": ["T05:x", "T05:y", "T01:y"],
                            "states": [{"state": "off", "static_stiffness_N_per_m": {"T05:y": k_static},
                                        "shapes_measured": False,
                                        "paired_shapes": shapes or [[1.0, 1.0, 1.0]]}]}}


def test_propose_names_the_measurement_that_separates_the_hypotheses():
    # the weights are nearly equal; the static stiffness tells C from A and B; the shapes tell nothing
    records = {"A": _record(1e12, 20.0, 1.0e8, 0.0), "B": _record(2e12, 20.1, 1.01e8, 1.0),
               "C": _record(4e12, 19.9, 2.0e8, 2.0), "D": _record(9e12, 5.0, 9e8, 30.0)}
    w = akaike_weights([0.0, 1.0, 2.0, 30.0])
    rows = [{"rank": i + 1, "hypothesis": n, "qaicc": q, "delta_qaicc": q, "weight": float(w[i])}
            for i, (n, q) in enumerate(zip("ABCD", (0.0, 1.0, 2.0, 30.0)))]
    opts = ProposalOptions(n_draws=0)
    df, summary = propose(records, rows, opts)
    assert summary["admissible"] == ["A", "B", "C"]  # D is 30 behind
    assert summary["target"] == "k_lateral_N_per_m3"  # the widest range (k_normal is the same in all)
    assert summary["before"] == pytest.approx(4.0)
    assert list(df["kind"]) == ["static stiffness", "weight", "shape"]
    best = summary["best"]
    assert best["measurement"] == "off: the static stiffness at T05:y"
    wn = w[:3] / w[:3].sum()
    assert best["k_lateral_N_per_m3_ratio_after"] == pytest.approx(2 * (wn[0] + wn[1]) + wn[2])
    assert df.iloc[-1]["k_lateral_N_per_m3_ratio_after"] == pytest.approx(4.0)  # the shapes are the same
    text = "\n".join(next_measurement_markdown(df, summary, opts))
    assert "The measurement that would narrow the reconstruction" in text
    assert "Next measurement: off: the static stiffness at T05:y" in text and "×4.00" in text
    assert "Not proposed: a damping ratio" in text


def test_propose_with_one_admissible_hypothesis_proposes_nothing():
    records = {"A": _record(1e12, 20.0, 1e8, 0.0), "B": _record(2e12, 25.0, 2e8, 10.0)}
    rows = [{"rank": 1, "hypothesis": "A", "qaicc": 0.0, "delta_qaicc": 0.0, "weight": 0.99},
            {"rank": 2, "hypothesis": "B", "qaicc": 10.0, "delta_qaicc": 10.0, "weight": 0.01}]
    df, summary = propose(records, rows, ProposalOptions(n_draws=0))
    assert df.empty and summary["best"] is None
    assert "nothing to separate" in "\n".join(next_measurement_markdown(df, summary))


def test_options_come_from_the_config_section_with_defaults():
    assert ProposalOptions.from_config({}) == ProposalOptions()
    got = ProposalOptions.from_config({"next_measurement": {"weight_uncertainty_pct": 1.0, "n_draws": 0}})
    assert got.weight_uncertainty_pct == 1.0 and got.n_draws == 0 and got.static_stiffness_uncertainty_pct == 5.0


def test_the_report_names_the_measurement_from_the_csv(tmp_path):
    from jointid.reporting.htmltable import html_table
    from jointid.reporting.hypotheses import next_measurement_html

    records = {"A": _record(1e12, 20.0, 1.0e8, 0.0), "B": _record(3e12, 26.0, 1.0e8, 1.0)}
    w = akaike_weights([0.0, 1.0])
    rows = [{"rank": i + 1, "hypothesis": n, "qaicc": q, "delta_qaicc": q, "weight": float(w[i])}
            for i, (n, q) in enumerate(zip("AB", (0.0, 1.0)))]
    df, _ = propose(records, rows, ProposalOptions(n_draws=50))
    df.to_csv(tmp_path / "next_measurements.csv", index=False)
    back = pd.read_csv(tmp_path / "next_measurements.csv")
    page = next_measurement_html(back, html_table)
    assert "The measurement that would narrow the reconstruction: the weight of the moving part" in page
    assert "k_lateral_N_per_m3 spans ×3.00" in page and "narrow it to ×1.00" in page
