"""Diagnosis numerics: score test, identifiability, correlation, reduced solver, variants, outputs."""

import itertools
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from jointid.correlate import pairing as correlate
from jointid.diagnosis import effects as E
from jointid.diagnosis.terms import BONDED_N_PER_M3, StateInfo
from jointid.diagnosis import terms as T
from jointid.reporting.diagnosis_history import append_history
from jointid.diagnosis.statistics import identifiability, score_test
from jointid.diagnosis.variants import EffectSpec, Variant
from jointid.fe.reduced import ReducedSolver
from jointid.threads import limit_threads
from jointid.config.typed import ModelSpec
from conftest import coarse_config_dict
from jointid.config.typed_diagnosis import DiagnosisSettings
from jointid.config.typed_diagnosis import DiagnoseJob
from conftest import truth_settings

ROOT = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------- score test (linear reference)
def _linear_case(seed, b_true):
    rng = np.random.default_rng(seed)
    n, p = 20, 3
    Jx = rng.normal(size=(n, p))
    jt = rng.normal(size=(n, 1)) + 0.5 * Jx[:, :1]
    y = Jx @ np.array([1.0, -2.0, 0.5]) + jt[:, 0] * b_true + rng.normal(size=n)
    a_hat = np.linalg.lstsq(Jx, y, rcond=None)[0]
    r = Jx @ a_hat - y  # model minus data, as in the diagnosis
    full = np.linalg.lstsq(np.hstack([Jx, jt]), y, rcond=None)[0]
    rss_r = float(r @ r)
    rss_f = float(np.sum((np.hstack([Jx, jt]) @ full - y) ** 2))
    return r, Jx, jt, full[-1], rss_r, rss_f


def test_score_test_equals_the_drop_in_residual_sum_of_squares_for_a_linear_model():
    r, Jx, jt, b_full, rss_r, rss_f = _linear_case(1, 3.0)
    st = score_test(r, Jx, jt, np.array([-np.inf]))
    assert st["score"] == pytest.approx(rss_r - rss_f, rel=1e-10)
    assert st["t_hat"][0] == pytest.approx(b_full, rel=1e-10)  # Frisch-Waugh-Lovell
    assert st["explained_fraction"] == pytest.approx((rss_r - rss_f) / rss_r, rel=1e-10)
    assert st["p_value"] < 1e-6


def test_score_test_one_sided_and_collinear():
    r, Jx, jt, b_full, *_ = _linear_case(2, -3.0)
    assert b_full < 0
    st = score_test(r, Jx, jt, np.array([0.0]))  # parameter must be >= 0: the data want < 0
    assert not st["sign_ok"] and st["explained_fraction"] == 0.0 and st["p_value"] == 1.0
    r, Jx, jt, b_full, rss_r, rss_f = _linear_case(3, 3.0)
    st = score_test(r, Jx, jt, np.array([0.0]))
    from scipy.stats import chi2

    assert st["p_value"] == pytest.approx(0.5 * chi2.sf(rss_r - rss_f, 1), rel=1e-8)
    coll = Jx @ np.array([[1.0], [2.0], [0.0]])
    st = score_test(r, Jx, coll, np.array([0.0]))
    assert st["collinearity"] < 1e-8 and st["score"] == 0.0


def test_score_test_ignores_round_off_columns_left_by_a_projection():
    # between-state contrasts of a state-independent parameter's sensitivity are zero up to the
    # solver's round-off; projecting a candidate onto the complement of that noise would remove an
    # arbitrary direction from it, so the columns are dropped relative to their norm before projection
    rng = np.random.default_rng(4)
    n = 9
    r, jt = rng.normal(size=n), rng.normal(size=(n, 1))
    scale = np.array([50.0, 80.0])
    noise = 1e-7 * rng.normal(size=(n, 2))  # what is left of two columns of norm 50 and 80
    exact = score_test(r, np.zeros((n, 0)), jt, np.array([-np.inf]))
    fragile = score_test(r, noise, jt, np.array([-np.inf]))
    assert abs(fragile["explained_fraction"] - exact["explained_fraction"]) > 1e-3  # the failure
    robust = score_test(r, noise, jt, np.array([-np.inf]), scale_x=scale)
    assert robust["explained_fraction"] == pytest.approx(exact["explained_fraction"], rel=1e-12)
    # a candidate with round-off sensitivity only explains nothing
    st = score_test(r, noise, 1e-8 * jt, np.array([-np.inf]), scale_x=scale, scale_t=np.array([10.0]))
    assert st["score"] == 0.0 and st["explained_fraction"] == 0.0


def test_identifiability_names_the_weak_combination():
    rng = np.random.default_rng(0)
    a = rng.normal(size=12)
    J = np.column_stack([a, 2 * a + 1e-6 * rng.normal(size=12), rng.normal(size=12)])
    out = identifiability(J, ["k_normal", "k_lateral", "mass"])
    assert out["flag"] and out["ratio"] < 1e-3
    assert "k_normal" in out["weak"] and "k_lateral" in out["weak"] and "mass" not in out["weak"]
    assert not identifiability(rng.normal(size=(12, 3)), list("abc"))["flag"]


# ---------------------------------------------------------------- correlation
def test_mac_pairing_lists_unpaired_modes():
    rng = np.random.default_rng(4)
    model = rng.normal(size=(60, 5))
    meas = model[:, [0, 2, 3]] * np.array([2.0, -1.0, 0.5]) + 0.01 * rng.normal(size=(60, 3))
    meas = np.hstack([meas, rng.normal(size=(60, 1))])  # a measured mode the model lacks
    meas[:5, 1] = np.nan  # unmeasured DOFs are ignored
    f_model = np.array([100.0, 200.0, 300.0, 400.0, 500.0])
    p = correlate.pair_modes([110, 290, 390, 450], f_model, meas, model, threshold=0.5)
    assert p.method == "mac"
    assert p.model_index.tolist() == [0, 2, 3, -1]
    assert p.unpaired_measured == [3]
    assert p.unpaired_model == [1]  # 200 Hz lies in the measured band and nobody took it
    tab = correlate.frequency_errors("s", [110, 290, 390, 450], f_model, p)
    assert tab.status.tolist() == ["paired"] * 3 + ["unpaired_measured", "unpaired_model"]
    assert tab.error_pct.iloc[0] == pytest.approx(100 * (100 - 110) / 110)
    summ = correlate.error_summary(tab)
    assert summ.n_paired.iloc[0] == 3 and summ.n_unpaired_measured.iloc[0] == 1


def test_ordered_assignment_is_optimal():
    rng = np.random.default_rng(5)
    for _ in range(20):
        cost = rng.random((3, 6))
        cols = correlate.ordered_assignment(cost)
        best = min(itertools.combinations(range(6), 3), key=lambda c: sum(cost[i, j] for i, j in enumerate(c)))
        assert tuple(cols) == best


def test_joint_state_pairing_keeps_one_mode_identity():
    # state B's model modes 1 and 2 swap order; measured mode 1 is the same physical mode in A and B
    fa = np.array([100.0, 200.0, 210.0, 400.0])
    fb = np.array([100.0, 230.0, 205.0, 400.0])
    tracks = [np.arange(4), np.arange(4)]
    pa, pb = correlate.pair_states_by_frequency([[198.0, 400.0], [233.0, 401.0]], [fa, fb], tracks)
    assert pa.model_index.tolist() == [1, 3] and pb.model_index.tolist() == [1, 3]


def test_shape_residuals_vanish_for_scaled_shapes_and_rank_points():
    labels = [f"P{i}:{d}" for i in range(4) for d in "xyz"]
    rng = np.random.default_rng(6)
    model = rng.normal(size=(12, 2))
    meas = -3.0 * model.copy()
    meas[0:3, 1] += 0.5  # point P0 is off in mode 2
    p = correlate.pair_modes([1.0, 2.0], [1.0, 2.0], meas, model)
    res = correlate.shape_residuals("s", meas, model, p, labels)
    assert np.abs(res[res["mode"] == 1].residual).max() < 1e-12
    pts = correlate.point_residuals(res)
    assert pts.point.iloc[0] == "P0"


# ---------------------------------------------------------------- reduced solver on the coarse rig
@pytest.fixture(scope="module")
def coarse():
    from jointid.config import load_config
    from jointid.fe.model import build_model

    limit_threads(1)
    cfg = coarse_config_dict()
    cfg = load_config(cfg)
    model = build_model(ModelSpec.from_config(cfg))
    return cfg, T.build_system(model, ModelSpec.from_config(cfg))


def _solver_at_reference(cfg, system) -> ReducedSolver:
    """A reduced solver of the coarse rig seeded at k_normal = k_lateral = 1e12, k_feed = 1e10 N/m^3."""
    theta = {"k_normal_N_per_m3": 1e12, "k_lateral_N_per_m3": 1e12, "k_feed_N_per_m3": 1e10}
    kc, mc = T.baseline_coefficients(system, ModelSpec.from_config(cfg), theta)
    return ReducedSolver(system, kc, mc, 10, [({f"K_top_y@{c}": 1.0 for c in range(4)}, {})], n_seed=6)


def test_reduced_solver_matches_the_full_solve_far_from_its_reference(coarse):
    from jointid.fe.modal import solve_modes

    cfg, system = coarse
    solver = _solver_at_reference(cfg, system)
    far = {"k_normal_N_per_m3": 3e11, "k_lateral_N_per_m3": 3e12, "k_feed_N_per_m3": 2e10}
    kc2, mc2 = T.baseline_coefficients(system, ModelSpec.from_config(cfg), far)
    kc2["K_railfix"] = 2e12
    mc2["M_table_edge"] = 2.0
    red = solver.solve(kc2, mc2, 10)
    full = solve_modes(system.K(kc2), system.M(mc2), 10, fixed=system.fixed)
    assert np.max(np.abs(red.freqs_Hz / full.freqs_Hz - 1)) < 1e-5
    # exact sensitivity of the reduced problem vs a central difference of the normal stiffness
    dk = {f"K_top_y@{c}": 1.0 for c in range(4)}
    h = 1e-4 * far["k_normal_N_per_m3"]
    lam = lambda s: solver.solve({**kc2, **{k: kc2[k] + s * h for k in dk}}, mc2, 10, refine=False).lam
    sol = solver.solve(kc2, mc2, 10, refine=False)
    fd = (lam(1) - lam(-1)) / (2 * h)
    assert np.allclose(solver.sensitivity(sol, dk, {}), fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max())


def test_reduced_solver_verify_confirms_by_sturm_count_and_falls_back_to_lanczos(coarse, monkeypatch):
    from jointid.fe import certify
    from jointid.fe.modal import solve_modes

    cfg, system = coarse
    solver = _solver_at_reference(cfg, system)
    near = {"k_normal_N_per_m3": 1.2e12, "k_lateral_N_per_m3": 1e12, "k_feed_N_per_m3": 1e10}
    kc2, mc2 = T.baseline_coefficients(system, ModelSpec.from_config(cfg), near)
    full = solve_modes(system.K(kc2), system.M(mc2), 10, fixed=system.fixed)
    lanczos_runs = solver.n_full_solves
    lines = []
    solver.log = lines.append
    err = solver.verify(kc2, mc2, 10)
    assert solver.n_full_solves == lanczos_runs  # confirmed by the count, no eigen-solve
    assert len(lines) == 1 and "certificate: residual error" in lines[0] and "Sturm count 10 modes" in lines[0]
    red = solver.solve(kc2, mc2, 10)
    assert err < 1e-6
    assert np.max(np.abs(red.freqs_Hz / full.freqs_Hz - 1)) < 1e-6
    # a count above the Ritz values (a mode the subspace lacks) sends it to a full Lanczos solve
    monkeypatch.setattr(certify, "count_pencil_modes_below", lambda *a, **k: 11)
    solver.sturm_counts.clear()  # else the count made above at this point answers again
    err = solver.verify(kc2, mc2, 10)
    assert solver.n_full_solves == lanczos_runs + 1 and err < 1e-5
    assert "certificate failed (Sturm count 11 for 10 Ritz values): full Lanczos solve" in lines[-1]
def test_variant_coefficient_derivatives(coarse):
    cfg, system = coarse
    var = Variant(system, DiagnosisSettings.from_config(cfg), [EffectSpec.candidate(E.EFFECTS["em_preload"])])
    x = var.x_start({"k_normal_N_per_m3": 8e11, "k_lateral_N_per_m3": 6e11, "k_feed_N_per_m3": 1e10})
    assert var.labels[-1] == "em_preload.beta" and x[-1] == 0.0
    on = StateInfo("on", 1000.0)
    kc, _ = var.coefficients(x, on)
    d = var.dcoefficients(x, on)
    w = system.carried_mass_kg * 9.81
    ratio = (1000.0 + w) / w
    assert d[-1][0]["K_top_y@1"] == pytest.approx(kc["K_top_y@1"] * math.log(ratio), rel=1e-6)
    assert d[0][0]["K_top_y@1"] == pytest.approx(kc["K_top_y@1"], rel=1e-6)  # d k / d ln k
    assert "K_flank_x@1" not in d[0][0]
    off = var.dcoefficients(x, StateInfo("off", 0.0))
    assert not off[-1][0]  # no motor force, no sensitivity to beta
    rail = Variant(system, DiagnosisSettings.from_config(cfg), [EffectSpec.candidate(E.EFFECTS["rail_fixing"])])
    xr = rail.x_start()
    dr = rail.dcoefficients(xr, on)[-1][0]["K_railfix"]
    p = E.EFFECTS["rail_fixing"].params[0]
    assert dr == pytest.approx(-BONDED_N_PER_M3 ** 2 / p.nominal, rel=1e-4)


# ---------------------------------------------------------------- outputs and workflow wiring
def test_history_appends_one_row_per_run(tmp_path):
    path = tmp_path / "results" / "history.csv"
    append_history(path, {"time_utc": "t1", "config_hash": "a", "variant": "baseline", "max_abs_error_pct": 2.0})
    append_history(path, {"time_utc": "t2", "config_hash": "b", "variant": "+em_preload", "max_abs_error_pct": 0.3})
    df = pd.read_csv(path)
    assert df.time_utc.tolist() == ["t1", "t2"] and df.max_abs_error_pct.tolist() == [2.0, 0.3]


def _snakemake_dry_run(tmp_path, extra: dict, target=None):
    for name in ("Snakefile", "config.yaml"):
        shutil.copy(ROOT / name, tmp_path / name)
    shutil.copytree(ROOT / "workflow", tmp_path / "workflow")
    shutil.copytree(ROOT / "data", tmp_path / "data")
    (tmp_path / "extra.yaml").write_text(yaml.safe_dump(extra))
    exe = Path(sys.executable).with_name("snakemake")
    cmd = [str(exe)] + ([target] if target else []) + ["-n", "-j1", "--configfile", "config.yaml", "extra.yaml"]
    return subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=120)


def test_workflow_diagnoses_registered_datasets_only(tmp_path):
    reg = {"datasets": {"paper": {"path": "data/paper", "states": ["power_off", "power_on"]}}}
    (tmp_path / "a").mkdir()
    out = _snakemake_dry_run(tmp_path / "a", reg, "results/diagnosis/paper/ranking.csv")
    assert out.returncode == 0, out.stderr[-2000:]
    assert "rule diagnose" in out.stdout and "results/diagnosis/paper/ranking.csv" in out.stdout
    # registered datasets replace the default: only `mine` is diagnosed
    (tmp_path / "b").mkdir()
    mine = {"datasets": {"mine": {"path": "data/paper", "states": ["power_off"]}}}
    out = _snakemake_dry_run(tmp_path / "b", mine)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "results/diagnosis/mine/ranking.csv" in out.stdout and "results/diagnosis/paper/" not in out.stdout
    # with no datasets registered, the run's measured dataset is diagnosed under its folder name
    (tmp_path / "c").mkdir()
    out = _snakemake_dry_run(tmp_path / "c", {"datasets": {}})
    assert out.returncode == 0, out.stderr[-2000:]
    assert "results/diagnosis/paper/ranking.csv" in out.stdout


# ---------------------------------------------------------------- bad input: stop early, say why
@pytest.mark.parametrize("extra, expected", [
    (["--config", "missing.yaml"], "--config missing.yaml: no such file"),
    (["--matrices", "missing.npz"], "--matrices missing.npz: no such file"),
    (["--effects", "{em_preload: {beta: 0.2}"], "--effects: not valid YAML"),
    (["--history", "."], "--history .: is a folder"),
])
def test_command_line_mistakes_are_reported_before_any_work(tmp_path, capsys, extra, expected):
    from jointid.diagnosis.__main__ import main

    rc = main(["--dataset", str(ROOT / "data" / "paper"), "--out", str(tmp_path / "out"),
               "--config", str(ROOT / "config.yaml"), *extra])
    err = capsys.readouterr().err
    assert rc == 1 and expected in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_out_naming_a_file_and_a_model_file_of_the_wrong_kind(tmp_path, capsys):
    from jointid.diagnosis.__main__ import main
    from jointid.errors import ModelError
    from jointid.fe.model import load_model

    (tmp_path / "f.txt").write_text("x")
    assert main(["--dataset", str(ROOT / "data" / "paper"), "--out", str(tmp_path / "f.txt")]) == 1
    assert "is a file, not a folder" in capsys.readouterr().err
    np.savez(tmp_path / "other.npz", freqs_Hz=np.arange(3.0))
    with pytest.raises(ModelError, match="not a jointid model file"):
        load_model(tmp_path / "other.npz")
    (tmp_path / "junk.npz").write_text("not a zip")
    # a damaged results file is named, with the fix (issue 51: jointid.io_errors.ResultReadError)
    from jointid.io_errors import ResultReadError

    with pytest.raises(ResultReadError, match="junk.npz: not a readable .npz archive.*make reproduce"):
        load_model(tmp_path / "junk.npz")


def test_measured_modes_below_the_tracked_band_are_refused(coarse):
    from jointid.diagnosis.variants import dataset_states
    from jointid.errors import DataError
    from jointid.data.dataset import read_dataset

    cfg, system = coarse
    ds = read_dataset(ROOT / "data" / "paper")
    cfg_low = {**cfg, "solver": {**cfg["solver"], "min_freq_Hz": 400.0}}
    with pytest.raises(DataError, match=r"power_off mode 1 at 344.3 Hz lies below solver.min_freq_Hz = 400"):
        dataset_states(ds, system, DiagnosisSettings.from_config(cfg_low))
    assert len(dataset_states(ds, system, DiagnosisSettings.from_config(cfg))) == 2


def test_fewer_frequencies_than_parameters_cannot_be_diagnosed(coarse):
    from jointid.diagnosis.loop import diagnose
    from jointid.diagnosis.variants import StateData
    from jointid.errors import DataError

    cfg, system = coarse
    data = [StateData(s, StateInfo(s, f), np.array([344.3]), None, 0.01)
            for s, f in (("power_off", 0.0), ("power_on", 1000.0))]
    with pytest.raises(DataError, match="2 measured frequencies for 3 fitted parameters"):
        diagnose(system, DiagnosisSettings.from_config(cfg), data)


def test_current_stage_gives_the_diagnosis_ladder_without_the_candidate_search(tmp_path):
    """Rule ``current`` (the quick half of the loop): baseline and configured effect calibrated by the
    same steps as the diagnosis, so its ladder equals the diagnosis' first ladder rows."""
    from conftest import diagnosis_rig

    from jointid.synthetic import generate as synth
    from jointid.diagnosis.loop import diagnose
    from jointid.stages.diagnosis import run_current

    rig = diagnosis_rig()
    cfg = {**rig["cfg"], "effects": {"em_preload": {"beta": 0.1}}}
    truth = synth.load_truth(Path(__file__).parent / "hidden" / "em_preload.yaml")
    synth.write_synthetic(truth, truth_settings(truth, rig["cfg"]), tmp_path / "ds", model=rig["model"])
    lines = []
    quick = run_current(DiagnoseJob.from_config(cfg), tmp_path / "ds", None, tmp_path / "out", model=rig["model"], log=lines.append)
    ladder = pd.read_csv(tmp_path / "out" / "ladder.csv")
    assert list(ladder.variant.unique()) == ["baseline", "+em_preload"]
    assert (tmp_path / "out" / "current.csv").exists() and (tmp_path / "out" / "compare.csv").exists()
    assert quick.ranking.empty and lines[-1].startswith("current model: baseline max ")
    full = diagnose(rig["system"], DiagnosisSettings.from_config(cfg), _data(rig, cfg, tmp_path), candidates=["added_mass_edge"], log=lambda m: None)
    cols = ["variant", "state", "max_abs_error_pct", "rms_error_pct", "chi2"]
    head = full.ladder[full.ladder.variant.isin(["baseline", "+em_preload"])][cols].reset_index(drop=True)
    pd.testing.assert_frame_equal(ladder[cols], head, rtol=1e-9)
    # the configured effect brings the error down to the noise (0.2 %) from well above it
    g = ladder.groupby("variant", sort=False).max_abs_error_pct.max()
    assert g["baseline"] > 1.0 and g["+em_preload"] < 1.0


def _data(rig, cfg, tmp_path):
    from jointid.data.dataset import read_dataset
    from jointid.diagnosis.variants import dataset_states

    ds = read_dataset(tmp_path / "ds", measuring_points=rig["system"].meta["points"])
    return dataset_states(ds, rig["system"], DiagnosisSettings.from_config(cfg))


def test_unexplained_verdict_says_what_was_tried_on_top_of_the_enabled_effects():
    """With one effect enabled and max_effects 2 no pair is searched on top (a model of three): the
    verdict names the enabled effect and why no pairs were tried; from the baseline it says pairs."""
    from types import SimpleNamespace as NS

    from jointid.diagnosis.verdict import unexplained_text

    lead = pd.DataFrame([{"effect": "base_support", "score": 1.0, "explained_fraction": 0.13,
                          "fit_p_value": 1e-43, "max_abs_error_pct_after": 7.29}])
    on_top = NS(variant=NS(effects=[NS(effect=NS(name="em_preload"))]), chi2=289.3, dof=12, p_value=8e-55,
                block_chi2=lambda: [("frequency", 289.3, 12)])
    txt = unexplained_text(on_top, lead, "power_off max 6.64 %", pd.DataFrame(), 2)
    assert "(single effects on top of em_preload tried; pairs on top would exceed diagnosis.max_effects = 2" in txt
    pairs = pd.DataFrame([{"effects": "a+b", "max_abs_error_pct_after": 7.3, "fit_p_value": 1e-43}])
    base = NS(variant=NS(effects=[]), chi2=543.9, dof=13, p_value=1e-100, block_chi2=lambda: [("frequency", 543.9, 13)])
    txt = unexplained_text(base, lead, "power_off max 11.4 %", pairs, 2)
    assert "(up to 2 effects at once tried; power_off" in txt and "on top of" not in txt


@pytest.mark.parametrize("x, dof", [(3.2, 2), (0.0, 1), (-1.0, 3), (1e3, 5), (5.0, 0), (np.inf, 2), (2.5, 2.5),
                                    (np.nan, 2), (0.3, 1)])
def test_chi2_survival_is_scipy_stats_number_for_number(x, dof):
    """The p-values without importing scipy.stats equal scipy.stats.chi2.sf exactly, edge cases included."""
    from scipy.stats import chi2

    from jointid.diagnosis.criteria import chi2_sf

    ref = float(chi2.sf(x, dof))
    assert chi2_sf(x, dof) == ref or (np.isnan(ref) and np.isnan(chi2_sf(x, dof)))


def test_an_effect_is_at_its_null_when_its_interval_reaches_test_variable_zero():
    """Analytic: the test variable t of an effect is 0 at its null (mass 0, compliance of an infinite
    stiffness).  With t = 0.3 and sd 0.1 the 95 % interval [0.104, 0.496] excludes the null; with sd 0.2
    ([-0.092, 0.692]) it holds it.  Only the parameters the refit adds beyond the current model count."""
    from types import SimpleNamespace

    from jointid.diagnosis.loop import at_null

    def fit(ts, sds, n_joint=2, n_slots_before=0):
        x = np.r_[np.zeros(n_joint), ts]
        cov = np.diag(np.r_[np.ones(n_joint), np.square(sds)])
        variant = SimpleNamespace(n_params=len(x), slots=[None] * len(ts))
        return SimpleNamespace(x=x, variant=variant, scaled_covariance=lambda: cov)

    assert not at_null(fit([0.3], [0.1]), 0)
    assert at_null(fit([0.3], [0.2]), 0)
    assert at_null(fit([0.0], [0.0]), 0)
    # an enabled effect far from its null (first slot) and a new one at its null: the new one decides
    assert at_null(fit([2.0, 0.01], [0.1, 0.1]), 1)
    assert not at_null(fit([0.01, 2.0], [0.1, 0.1]), 1)
