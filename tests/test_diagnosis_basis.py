"""The run model's shared reduced basis (rule diagnosis_basis, jointid.stages.basis; issue 39: one
basis built once, used by the hypotheses and the diagnosis).  The hypothesis here has a steel table
(another modulus, density and Poisson's ratio) and heavier motors: its system has the table's solid
terms besides the run's, and the shared basis serves it once it projects them.

A hypothesis on the run's model started from the shared basis must give the fit it gives when its
reduced solver is built afresh: parameters to 1e-4 relative and AICc to 0.01 (issue 39 asks 1e-4 and
0.1).  The answers are certified in the full space either way; what differs is where the least-squares
search stops (chi-square 2e-6 relative apart on the coarse rig), so chi-square is held to 1e-5.  A basis of another model is not taken: the job
starts afresh and says so.
"""

import numpy as np
import pytest

from conftest import coarse_config_dict
from jointid.config import load_config
from jointid.config.typed import ModelSpec
from jointid.fe.model import build_model, save_model
from jointid.stages.basis import run_basis
from jointid.stages.hypotheses import run_hypotheses, run_hypothesis
from jointid.config.typed_diagnosis import DiagnosisSettings
from jointid.config.hypotheses import HypothesisJob
from jointid.reconstruction.hypotheses import check_hypothesis_effects

HYPOTHESIS = {"description": "a steel table and 3 kg more on each motor (coefficients of the run's model)",
              "overrides": {"rig": {"table": {"material": "steel"}, "motors": {"mass_each_kg": 6.0}}}}
LIGHT = {"description": "1 kg motors (a coefficient of the run's model)",
         "overrides": {"rig": {"motors": {"mass_each_kg": 1.0}}}}


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    raw = coarse_config_dict()
    raw["hypotheses"] = {"heavy": HYPOTHESIS, "light": LIGHT}
    cfg = load_config(raw)
    tmp = tmp_path_factory.mktemp("basis")
    matrices = tmp / "matrices.npz"
    save_model(build_model(ModelSpec.from_config(cfg)), matrices)
    basis = tmp / "diagnosis_basis.npz"
    lines = []
    run_basis(DiagnosisSettings.from_config(cfg), str(matrices), str(basis), log=lines.append)
    return cfg, tmp, matrices, basis, lines


def _fit(case, basis, name):
    cfg, tmp, matrices, _, _ = case
    lines = []
    rec = run_hypothesis(HypothesisJob.from_config(cfg, "heavy", check_hypothesis_effects), str(matrices), str(tmp / f"{name}.json"), basis=basis, log=lines.append)
    return rec, lines


@pytest.fixture(scope="module")
def heavy_shared(case):
    """The heavy hypothesis fitted in a job of its own from the shared basis: ``(record, log lines)``
    (both tests below compare with it)."""
    return _fit(case, str(case[3]), "shared")


def test_a_hypothesis_from_the_shared_basis_fits_as_from_its_own(case, heavy_shared):
    _, _, _, basis, built = case
    assert any("diagnosis basis:" in m and "vectors" in m for m in built), built
    shared, lines = heavy_shared
    assert any("of the shared basis" in m and m.endswith("projecting the terms it was not kept with: "
                                                         "K_lambda_table, K_solid_table, M_solid_table")
               for m in lines), lines
    assert not shared["own_model"]
    fresh, lines_fresh = _fit(case, None, "fresh")
    assert not any("shared basis" in m for m in lines_fresh)
    theta = {p["parameter"]: p["value"] for p in shared["parameters"]}
    theta_f = {p["parameter"]: p["value"] for p in fresh["parameters"]}
    worst = max(abs(theta[k] / theta_f[k] - 1) for k in theta_f)
    print(f"shared basis against a fresh solver: chi2 {shared['chi2']:.9g} / {fresh['chi2']:.9g}, "
          f"parameters {worst:.1e} (relative)")
    assert shared["chi2"] == pytest.approx(fresh["chi2"], rel=1e-5)
    assert worst <= 1e-4
    assert shared["aicc"] == pytest.approx(fresh["aicc"], abs=0.01)


def test_hypotheses_in_one_job_fit_as_in_their_own(case, heavy_shared):
    """Rule hypotheses_run_model: the coefficient-only hypotheses fitted in one process on one set of terms and
    one reduced solver, grown from fit to fit, give each the fit of its own job to the solver's tolerance
    (the same bounds as the shared basis above); the second says it takes the solver of the first.  Only the
    admissible ones are certified (Sturm count) and carry the next measurement's predictions."""
    cfg, tmp, matrices, basis, _ = case
    jobs = [HypothesisJob.from_config(cfg, n, check_hypothesis_effects) for n in ("light", "heavy")]
    lines = []
    together = run_hypotheses(jobs, str(matrices), [str(tmp / "t_light.json"), str(tmp / "t_heavy.json")],
                              basis=str(basis), log=lines.append)
    assert any(m.startswith("hypothesis heavy (2/2") and m.endswith("the reduced solver of the hypotheses before")
               for m in lines), lines
    from jointid.reconstruction.ranking import rank_hypotheses

    rows, _, _ = rank_hypotheses({r["hypothesis"]: r for r in together})
    assert {r["hypothesis"]: r["certified"] for r in rows} == {r["hypothesis"]: r["admissible"] for r in rows}
    assert all(("predictions" in r) == r["certified"] for r in together)
    for job, rec in zip(jobs, together):
        alone = heavy_shared[0] if job.name == "heavy" else \
            run_hypothesis(job, str(matrices), str(tmp / f"a_{job.name}.json"), basis=str(basis), log=lambda m: None)
        theta = {p["parameter"]: p["value"] for p in rec["parameters"] if not p.get("fixed")}
        theta_a = {p["parameter"]: p["value"] for p in alone["parameters"] if not p.get("fixed")}
        worst = max(abs(theta[k] / theta_a[k] - 1) for k in theta_a if theta_a[k] != 0.0)
        print(f"{job.name}: in one job against its own: chi2 {rec['chi2']:.9g} / {alone['chi2']:.9g}, "
              f"parameters {worst:.1e} (relative)")
        assert rec["hypothesis"] == job.name and not rec["own_model"]
        assert rec["chi2"] == pytest.approx(alone["chi2"], rel=1e-5)
        assert worst <= 1e-4
        assert rec["aicc"] == pytest.approx(alone["aicc"], abs=0.01)


def test_a_basis_of_another_model_is_not_taken(case, tmp_path):
    cfg, _, _, basis, _ = case
    raw = coarse_config_dict()
    raw["hypotheses"] = {"heavy": HYPOTHESIS}
    raw["mesh"] = {**raw.get("mesh", {}), "max_cell_size_m": 0.10}
    other = load_config(raw)
    matrices = tmp_path / "other.npz"
    save_model(build_model(ModelSpec.from_config(other)), matrices)
    lines = []
    rec = run_hypothesis(HypothesisJob.from_config(other, "heavy", check_hypothesis_effects), str(matrices), str(tmp_path / "h.json"), basis=str(basis), log=lines.append)
    assert any("kept for another model: starting afresh" in m for m in lines), lines
    assert np.isfinite(rec["chi2"])


def _wide(raw: dict) -> dict:
    """A hypothesis with a model of its own that the data reject: the rails 50 mm further apart."""
    return {"description": "the rails 50 mm further apart (its own model)",
            "overrides": {"rig": {"rails": {"spacing_m": float(raw["rig"]["rails"]["spacing_m"]) + 0.05}}}}


def test_hypotheses_on_models_of_their_own_are_certified_only_where_admissible(tmp_path):
    """Rule hypotheses_run_model with hypotheses apart (issue 54: a rejected hypothesis needs its fit, not a
    certificate): their jobs leave the certificate pending; ranked with the run model's, an admissible one
    (a table 0.2 mm thicker: the run's model again, to the eye of the data) is fitted again on its own model
    and certified, a rejected one (the rails 50 mm further apart) keeps its fit and says why it has no Sturm
    count.  After the job no record is pending, and exactly the admissible ones carry a certificate and the
    next measurement's predictions."""
    from jointid.reconstruction.hypotheses import CERTIFIED, PENDING, not_certified
    from jointid.reconstruction.ranking import rank_hypotheses

    raw = coarse_config_dict()
    thick = float(raw["rig"]["table"]["thickness_m"]) + 2e-4
    raw["hypotheses"] = {"light": LIGHT,
                         "thicker": {"description": "the table 0.2 mm thicker (its own model)",
                                     "overrides": {"rig": {"table": {"thickness_m": thick}}}},
                         "wide": _wide(raw)}
    cfg = load_config(raw)
    matrices = tmp_path / "matrices.npz"
    save_model(build_model(ModelSpec.from_config(cfg)), matrices)
    jobs = {n: HypothesisJob.from_config(cfg, n, check_hypothesis_effects) for n in raw["hypotheses"]}
    assert jobs["thicker"].own_model and jobs["wide"].own_model and not jobs["light"].own_model
    searched = []
    for name in ("thicker", "wide"):
        rec = run_hypothesis(jobs[name], str(matrices), str(tmp_path / f"{name}_search.json"), certify=False,
                             log=lambda m: None)
        assert not rec["certified"] and rec["certificate"] == PENDING and "predictions" not in rec
        searched.append(str(tmp_path / f"{name}_search.json"))
    lines = []
    run_hypotheses([jobs["light"]], str(matrices), [str(tmp_path / "light.json")], others=searched,
                   apart=[jobs["thicker"], jobs["wide"]],
                   apart_jsons=[str(tmp_path / "thicker.json"), str(tmp_path / "wide.json")], log=lines.append)
    from jointid import io

    final = {n: io.read_json(str(tmp_path / f"{n}.json")) for n in ("light", "thicker", "wide")}
    rows, _, _ = rank_hypotheses(final)
    admissible = {r["hypothesis"]: bool(r.get("admissible")) for r in rows}
    assert admissible["thicker"] and not admissible["wide"], admissible
    for name, rec in final.items():
        assert rec["certified"] == admissible[name]
        assert rec["certificate"] == (CERTIFIED if admissible[name] else not_certified(rec["search_tol"]))
        assert ("predictions" in rec) == rec["certified"]
        assert rec["own_model"] == (name != "light")
    assert "hypothesis thicker: admissible, certified" in lines and "hypothesis wide: admissible, certified" not in lines


@pytest.mark.extended  # a model file of an older layout; the default suite fits the hypotheses apart on today's
def test_a_model_file_without_per_part_solids_still_writes_the_hypotheses_apart(tmp_path):
    """A model file written before the solids were kept per part: the job on the run's model fits each
    hypothesis as its own job would, certified, and writes the records of those apart too (their jobs left
    the certificate to it)."""
    from jointid import io
    from jointid.reconstruction.hypotheses import CERTIFIED

    raw = coarse_config_dict()
    raw["hypotheses"] = {"light": LIGHT,
                         "wide": _wide(raw)}
    cfg = load_config(raw)
    model = build_model(ModelSpec.from_config(cfg))
    model.meta.pop("solids", None)
    matrices = tmp_path / "matrices.npz"
    save_model(model, matrices)
    light, wide = (HypothesisJob.from_config(cfg, n, check_hypothesis_effects) for n in ("light", "wide"))
    assert light.overrides_model and wide.own_model
    run_hypothesis(wide, str(matrices), str(tmp_path / "wide_search.json"), certify=False, log=lambda m: None)
    run_hypotheses([light], str(matrices), [str(tmp_path / "light.json")], others=[str(tmp_path / "wide_search.json")],
                   apart=[wide], apart_jsons=[str(tmp_path / "wide.json")], log=lambda m: None)
    for name in ("light", "wide"):
        rec = io.read_json(str(tmp_path / f"{name}.json"))
        assert rec["certified"] and rec["certificate"] == CERTIFIED and "predictions" in rec
