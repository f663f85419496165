"""The diagnosis when the data are incomplete or cannot decide (docs/effects.md, "When the data cannot decide").

Each case synthesises a dataset (fixed seed) from a truth the diagnosis never sees, on the coarse rig:

* partial data — fewer modes, shapes in one direction only, one mode's shape missing in one state:
  the hidden effect still ranks first and no NaN reaches a table, the verdict or the history;
* two compliances on one load path — the verdict names both as indistinguishable and proposes a
  measurement; measuring up to the proposed mode makes the true one win;
* two effects at once — the verdict names the pair, the ladder reaches the noise level;
* the contact law with three force levels — beta and the block preload both recovered within their
  intervals; with two, the verdict says only the stiffness ratio is identified, and that ratio's
  interval holds the true one;
* a small effect that the joint parameters absorb — no candidate "explains", the verdict says what
  the joints could be hiding.
"""

import json

import numpy as np
import pytest

from jointid.data.dataset import read_dataset, write_dataset
from jointid.synthetic import generate as synth
from jointid.diagnosis.effects import pressure_ratio
from jointid.reporting.diagnosis_history import history_row
from jointid.diagnosis.loop import diagnose
from jointid.diagnosis.memo import FitMemo
from jointid.reporting.diagnosis_outputs import write_outputs
from jointid.diagnosis.terms import StateInfo
from jointid.diagnosis.variants import dataset_states
from conftest import diagnosis_rig, ladder_text, print_summary
from jointid.config.typed_diagnosis import DiagnosisSettings
from conftest import truth_settings

JOINTS = {"k_normal_N_per_m3": 8.0e11, "k_lateral_N_per_m3": 6.0e11}
TWO_STATES = {"power_off": {"em_force_N": 0.0}, "power_on": {"em_force_N": 1000.0}}
SUMMARY: dict = {}


@pytest.fixture(scope="module")
def rig():
    """The coarse rig of the synthetic diagnosis tests (:func:`conftest.diagnosis_rig`)."""
    return diagnosis_rig()


def truth(effects: dict, *, seed: int, max_modes: int = 10, states=None, band=(100.0, 3500.0), **meas) -> dict:
    return {"joints": JOINTS, "states": states or TWO_STATES, "effects": effects,
            "measurement": {"band_Hz": list(band), "max_modes": max_modes, "shapes": True, **meas},
            "noise": {"seed": seed, "frequency_pct": 0.2, "shape_pct": 2.0}}


def run_case(rig, t: dict, folder, *, drop=None, shape_residuals=True, **kw):
    """Synthesise ``t`` into ``folder`` (shape rows where ``drop(shapes)`` is true removed), diagnose it
    (``shape_residuals`` False: the shapes pair the modes only, ``diagnosis.shape_residuals``)."""
    out = synth.synthesise(t, truth_settings(t, rig["cfg"]), model=rig["model"])
    shapes = out["shapes"]
    if drop is not None:
        shapes = shapes[~drop(shapes)]
    write_dataset(folder, out["modes"], shapes, out["frf"], conditions=out["conditions"],
                  measuring_points=out["points"])
    ds = read_dataset(folder, measuring_points=rig["system"].meta["points"])
    data = dataset_states(ds, rig["system"], DiagnosisSettings.from_config(rig["cfg"]))
    # a fresh reduced solver per case: a subspace grown over unrelated cases only slows the solves
    cfg = {**rig["cfg"], "diagnosis": {**(rig["cfg"].get("diagnosis") or {}), "shape_residuals": shape_residuals}}
    res = diagnose(rig["system"], DiagnosisSettings.from_config(cfg), data, log=lambda m: None, **kw)
    return res, data


def no_nan_anywhere(res, tmp_path):
    """No NaN in the verdict, the ladder's errors, the history row or any written file's text."""
    assert "nan" not in res.verdict.lower()
    assert np.isfinite(res.ladder[["max_abs_error_pct", "rms_error_pct", "chi2", "p_value"]].to_numpy(float)).all()
    row = history_row(res, "synthetic", "x")
    assert "nan" not in json.dumps(row).lower()
    write_outputs(res, tmp_path / "out", "synthetic", {"time_utc": "now", "config_hash": "x"})
    for f in (tmp_path / "out").iterdir():
        if f.suffix in (".csv", ".json"):
            assert "nan" not in f.read_text().lower().replace("nanmean", ""), f.name


@pytest.mark.extended
def test_partial_data_finds_the_hidden_effect(rig, tmp_path):
    """7 modes, shapes in y only, mode 3's shape missing in power_on: one missing shape removes that
    mode's shape information only (it is paired by frequency), the state is not poisoned."""
    t = truth({"added_mass_table": {"mass_kg": 4.0}}, seed=21, max_modes=7, directions=["y"])
    res, data = run_case(rig, t, tmp_path / "ds",
                         drop=lambda sh: (sh["state"] == "power_on") & (sh["mode"] == 3))
    assert data[1].shapes is not None and np.isnan(data[1].shapes[:, 2]).all()
    top = res.ranking.iloc[0]
    assert top.effect == "added_mass_table" and bool(top.explains), res.verdict
    assert res.explained_by == "added_mass_table"
    base = res.ladder[res.ladder.variant == "baseline"]
    assert (base.n_paired == 7).all()  # every measured mode paired in both states
    no_nan_anywhere(res, tmp_path)
    SUMMARY["partial data"] = dict(text=res.verdict, truth="added_mass_table", rank=1, verdict=res.explained_by,
                                   ladder=ladder_text(res.ladder))


@pytest.mark.extended  # make test: the frequency-only tie of tests/test_shape_residuals.py
def test_near_collinear_effects_are_named_together_and_a_measurement_decides(rig, tmp_path):
    """An elastic foundation and a compliant rail fixing load the same path: with four frequencies (shape
    rows off: with them the shapes decide, tests/test_shape_residuals.py) both refits reach the noise; the
    verdict names both, proposes a measurement, and measuring the modes up to the proposed one makes
    the truth win alone."""
    t = truth({"base_support": {"k_foundation_N_per_m3": 3.0e11}}, seed=40, max_modes=4)
    res, _ = run_case(rig, t, tmp_path / "ds", shape_residuals=False)
    assert set(res.explained_by.split(" or ")) == {"base_support", "rail_fixing"}, res.verdict
    assert "cannot tell them apart" in res.verdict
    top = res.ranking.iloc[0]
    assert top.indistinguishable_from in ("base_support", "rail_fixing") and top.indistinguishable_from != top.effect
    assert len(res.next_measurements) >= 1
    best = res.next_measurements.iloc[0]
    assert best.expected_delta_chi2 > 9.0  # separates them by more than 3 sigma
    write_outputs(res, tmp_path / "out", "synthetic", {})
    verdict = json.loads((tmp_path / "out" / "verdict.json").read_text())
    assert verdict["kind"] == "indistinguishable" and set(verdict["effects"]) == {"base_support", "rail_fixing"}
    # the proposed measurement: the test band extended to the proposed mode (every mode below it measured)
    f_new = max(float(v.split()[-2]) for v in best.predictions.split("; "))
    t2 = truth({"base_support": {"k_foundation_N_per_m3": 3.0e11}}, seed=40, max_modes=40,
               band=(100.0, 1.02 * f_new))
    res2, _ = run_case(rig, t2, tmp_path / "ds2", shape_residuals=False)
    assert res2.explained_by == "base_support", res2.verdict
    SUMMARY["near-collinear"] = dict(text=res.verdict, truth="base_support", rank=f"tied ({res.explained_by})",
                                     verdict=res.explained_by, ladder=ladder_text(res.ladder),
                                     measurement=best.measurement, after=res2.explained_by,
                                     ladder_after=ladder_text(res2.ladder))
    SUMMARY["near-collinear, band extended"] = dict(text=res2.verdict, truth="base_support", rank=1,
                                                    verdict=res2.explained_by, ladder=ladder_text(res2.ladder))


@pytest.mark.extended
def test_two_effects_at_once_are_named_as_a_pair_and_enabling_one_leaves_the_other_first(rig, tmp_path):
    """The contact law (state-dependent) and a mass on the table edge (not): no single candidate
    explains, the pair does, and the ladder shows baseline -> +A -> +A+B at the noise level.  Then the
    loop: enable A (no value given) and the next run ranks B first on top of it, explaining the data,
    with the fit the last run made of the pair (the same question, so the recorded fits answer it)."""
    t = truth({"em_preload": {"beta": 0.2}, "added_mass_edge": {"mass_kg": 1.0}}, seed=33)
    memo = FitMemo()
    # frequency rows only, in both runs (the second's configuration says so): the same question twice
    res, data = run_case(rig, t, tmp_path / "ds", memo=memo, shape_residuals=False)
    assert set(res.explained_by.split("+")) == {"em_preload", "added_mass_edge"}, res.verdict
    assert res.verdict.startswith("Missing effects:")
    assert not res.ranking.explains.any()
    steps = list(dict.fromkeys(res.ladder.variant))
    assert steps[0] == "baseline" and steps[-1].endswith("(suggested)") and len(steps) == 3
    last = res.ladder[res.ladder.variant == steps[-1]]
    assert last.p_value.iloc[0] >= 0.01 and float(last.max_abs_error_pct.max()) < 4 * 0.2
    comb = res.combinations.iloc[0]
    assert bool(comb.explains) and "em_preload.beta" in comb.estimates
    no_nan_anywhere(res, tmp_path)
    SUMMARY["two effects"] = dict(text=res.verdict, truth="em_preload+added_mass_edge", rank="pair first",
                                  verdict=res.explained_by, ladder=ladder_text(res.ladder))

    a, b = res.explained_by.split("+")
    pair = res.combinations.set_index("effects").loc[f"{a}+{b}"]
    again = FitMemo(memo.records)
    cfg = {**rig["cfg"], "effects": {a: {}}, "diagnosis": {**rig["cfg"]["diagnosis"], "shape_residuals": False}}
    second = diagnose(rig["system"], DiagnosisSettings.from_config(cfg), data, memo=again, solver=res.solver, drift=False, log=lambda m: None)
    top = second.ranking.iloc[0]
    assert top.effect == b and bool(top.explains) and second.explained_by == b, second.verdict
    # the pair's optimum, to the solver tolerance (1e-6 in each eigenvalue: 5e-7 / sigma in each residual)
    n = sum(len(d.f_meas) for d in data)
    assert abs(top.fit_chi2 - pair.fit_chi2) <= 2 * np.sqrt(pair.fit_chi2 * n) * 5e-7 / data[0].sigma_rel
    assert again.hits > 0
    now = second.ladder[second.ladder.variant == f"+{a}"]
    after = second.ladder[second.ladder.variant == f"+{b} (suggested)"]
    assert float(now.max_abs_error_pct.max()) > 4 * 0.2  # one of the two enabled: the error is still there
    assert after.p_value.iloc[0] >= 0.01 and float(after.max_abs_error_pct.max()) < 4 * 0.2
    SUMMARY["two effects, one enabled"] = dict(text=second.verdict, truth="em_preload+added_mass_edge",
                                               rank=1, verdict=second.explained_by,
                                               ladder=ladder_text(second.ladder))


@pytest.mark.extended
def test_candidates_on_top_of_two_enabled_effects_never_end_worse_than_the_model(rig, tmp_path):
    """Two effects enabled (the ladder baseline -> +A -> +A+B): every candidate on top is refitted as
    the pair it makes with B, from B's rung below (itself refitted on A's rung, then on the
    baseline), and no refit ends above the current model's chi-square.  Frequency rows only: with
    ~860 shape rows at their noise no candidate explains 1 % of the chi-square, so none is refitted."""
    t = truth({"em_preload": {"beta": 0.2}, "added_mass_edge": {"mass_kg": 1.0}}, seed=33)
    cfg = {**rig["cfg"], "effects": {"em_preload": {}, "added_mass_edge": {}},
           "diagnosis": {**(rig["cfg"].get("diagnosis") or {}), "shape_residuals": False}}
    out = synth.synthesise(t, truth_settings(t, rig["cfg"]), model=rig["model"])
    write_dataset(tmp_path / "ds", out["modes"], out["shapes"], out["frf"], conditions=out["conditions"],
                  measuring_points=out["points"])
    data = dataset_states(read_dataset(tmp_path / "ds", measuring_points=rig["system"].meta["points"]),
                          rig["system"], DiagnosisSettings.from_config(cfg))
    res = diagnose(rig["system"], DiagnosisSettings.from_config(cfg), data, candidates=["added_mass_table", "base_support"], drift=False,
                   compare=False, log=lambda m: None)
    assert list(dict.fromkeys(res.ladder.variant))[:3] == ["baseline", "+em_preload", "+added_mass_edge"]
    current = res.ladder[res.ladder.variant == "+added_mass_edge"]
    assert current.p_value.iloc[0] >= 0.01  # both hidden effects in the model: within the noise
    refitted = res.ranking[res.ranking.fit_chi2.notna()]
    assert len(refitted) >= 1
    chi2_now = float(current.chi2.iloc[0])
    assert (refitted.fit_chi2 <= chi2_now * (1 + 1e-6) + 1e-6).all(), refitted[["effect", "fit_chi2"]]
    assert res.explained_by == "none needed" and not res.ranking.explains.any()


@pytest.mark.extended
def test_contact_law_with_three_force_levels_identifies_beta_and_preload(rig, tmp_path):
    """Force levels 0, 1000 and 2000 N, true beta 0.4 and block preload 300 N: the profile over the
    preload recovers both within their intervals."""
    states = {"f0": {"em_force_N": 0.0}, "f1": {"em_force_N": 1000.0}, "f2": {"em_force_N": 2000.0}}
    t = truth({"em_preload": {"beta": 0.4, "preload_N": 300.0}}, seed=35, states=states)
    res, _ = run_case(rig, t, tmp_path / "ds")
    assert res.explained_by == "em_preload", res.verdict
    top = res.ranking.iloc[0]
    prof = res.fits["+em_preload"].preload_profile
    assert prof["low"] <= 300.0 <= prof["high"], prof
    assert top.ci95_low <= 0.4 <= top.ci95_high, (top.estimate, top.ci95_low, top.ci95_high)
    assert "separates beta from the block preload" in res.verdict
    SUMMARY["em_preload, 3 levels"] = dict(
        text=res.verdict, truth="em_preload beta 0.4, P 300 N", rank=1, verdict=res.explained_by,
        ladder=ladder_text(res.ladder),
        estimate=(f"beta {top.estimate:.3f} [{top.ci95_low:.3f}, {top.ci95_high:.3f}], "
                  f"P {prof['preload_N']:.0f} N [{prof['low']:.0f}, {prof['high']:.0f}]"))


@pytest.mark.extended
def test_contact_law_with_two_force_levels_reports_the_ratio(rig, tmp_path):
    """Two force levels, true beta 0.4 with a 300 N block preload: the diagnosis fits beta at P = 0 and
    says beta and P are not separable; the stiffness ratio it reports holds the true ratio."""
    t = truth({"em_preload": {"beta": 0.4, "preload_N": 300.0}}, seed=36)
    res, data = run_case(rig, t, tmp_path / "ds")
    assert res.explained_by == "em_preload", res.verdict
    assert "not separately identifiable" in res.verdict and "stiffness ratio" in res.verdict
    rho = pressure_ratio(rig["system"], StateInfo("power_on", 1000.0), {"preload_N": 300.0})
    true_ratio = float(np.exp(np.mean(np.log(rho ** 0.4))))
    text = res.identifiable["+em_preload"]
    lo, hi = (float(v) for v in text.split("95 % CI ")[1].split(")")[0].split(" .. "))
    assert lo <= true_ratio <= hi, (true_ratio, text)
    curve = res.preload_curve
    assert len(curve) >= 3 and curve.chi2.max() - curve.chi2.min() < 1.0  # equally good along the curve
    SUMMARY["em_preload, 2 levels"] = dict(text=res.verdict, rank=1,
                                           truth=f"em_preload beta 0.4, P 300 N (ratio {true_ratio:.3f})",
                                           verdict=res.explained_by, ladder=ladder_text(res.ladder),
                                           estimate=text.split(" With")[0])


def test_absorbed_effect_is_said_and_nothing_explains(rig, tmp_path):
    """A compliant rail fixing (1e13 N/m^3) with four modes: the refitted joints take it up, the
    baseline fits within the noise; no candidate may claim to explain, and the verdict says which
    effects the joints could be hiding and by how much they would be biased."""
    t = truth({"rail_fixing": {"k_railfix_N_per_m3": 1.0e13}}, seed=40, max_modes=4)
    res, _ = run_case(rig, t, tmp_path / "ds", shape_residuals=False)  # with shapes the joints cannot imitate it
    assert res.explained_by == "none needed", res.verdict
    assert not res.ranking.explains.any()
    assert "cannot tell rail_fixing from a change of the joint parameters" in res.verdict
    row = res.ranking[res.ranking.effect == "rail_fixing"].iloc[0]
    assert bool(row.absorbed) and abs(row.absorbed_bias_pct) > 3.0
    no_nan_anywhere(res, tmp_path)
    SUMMARY["absorbed"] = dict(text=res.verdict, truth="rail_fixing 1e13", rank="-", verdict=res.explained_by,
                               ladder=ladder_text(res.ladder))


def test_too_few_modes_is_refused_with_a_clear_message(rig, tmp_path):
    """One state, two modes, two fitted parameters: nothing can be said, and the message says why."""
    from jointid.errors import DataError

    t = truth({"added_mass_table": {"mass_kg": 4.0}}, seed=3, max_modes=2, states={"power_off": {"em_force_N": 0.0}})
    with pytest.raises(DataError, match="2 measured frequencies for 2 fitted parameters"):
        run_case(rig, t, tmp_path / "ds")


def test_summary_table(capsys):
    """Print truth, rank, verdict and error ladder of every case (pytest -s)."""
    print_summary(SUMMARY, capsys)


def test_a_pair_that_ties_with_its_own_single_yields_the_lead_to_the_single():
    """Parsimony: the second effect of a pair within the tie window of its own single is not supported
    against it, so the single leads; a pair clearly better than its singles, or tied with an unrelated
    single, keeps the lead."""
    from jointid.diagnosis.judging import parsimonious_order

    tied = [(-2104.7, "a+b"), (-2101.8, "a"), (-381.5, "c"), (-62.9, "b")]
    assert parsimonious_order(tied, 4.0) == ["a", "a+b", "c", "b"]
    clear = [(-2104.7, "a+b"), (-2090.0, "a"), (-62.9, "b")]
    assert parsimonious_order(clear, 4.0) == ["a+b", "a", "b"]
    unrelated = [(-50.0, "a + b"), (-48.0, "c")]
    assert parsimonious_order(unrelated, 4.0) == ["a + b", "c"]
    both = [(-50.0, "a+b"), (-47.5, "b"), (-49.0, "a")]
    assert parsimonious_order(both, 4.0) == ["a", "a+b", "b"]  # the better of the two singles
    assert parsimonious_order([], 4.0) == []
