"""Coefficient-only hypotheses on the run's model (issue 41, items 3 and 6).

A hypothesis that changes only a part's material (Young's modulus, density, Poisson's ratio), or the
motor mass, is a change of coefficients of the run's model (``reconstruction.hypotheses.needs_own_model``, ``fe.model.solid_coefficients``):
fitted on the run's model it must give the fit it gives on a model built with the change (chi-square to
1e-6 relative, AICc to 0.1), on the paper's data and the coarse mesh.  An attraction given by a
hypothesis reaches its fit in place of the dataset's.
"""

import math

import pytest

from jointid import io
from jointid.config import load_config
from jointid.config.hypotheses import hypothesis_config, needs_own_model
from jointid.reconstruction.hypotheses import fit_hypothesis
from jointid.diagnosis.terms import build_system
from jointid.fe.model import build_model, save_model
from jointid.stages.hypotheses import measured_states, run_hypothesis
from jointid.threads import limit_threads
from jointid.config.typed import ModelSpec
from conftest import coarse_config_dict
from jointid.config.typed_diagnosis import DiagnosisSettings
from jointid.config.hypotheses import HypothesisJob
from jointid.config.hypotheses import LinkedLaw
from jointid.reconstruction.hypotheses import check_hypothesis_effects

# a lighter table (another aluminium: E and density changed, Poisson's ratio kept) and 1 kg motors
LIGHT = {"overrides": {"materials": {"aluminium_light": {"youngs_modulus_Pa": 6.0e10, "poisson_ratio": 0.33,
                                                         "density_kg_per_m3": 1350.0}},
                       "rig": {"table": {"material": "aluminium_light"}, "motors": {"mass_each_kg": 1.0}}}}
# a steel table (E, density and Poisson's ratio 0.33 -> 0.30: the Lame split) and 1 kg motors
STEEL = {"overrides": {"rig": {"table": {"material": "steel"}, "motors": {"mass_each_kg": 1.0}}}}


def _cfg():
    raw = coarse_config_dict()
    raw["hypotheses"] = {}
    return load_config(raw)


def test_which_overrides_need_a_model_of_their_own():
    cfg = _cfg()
    coefficient_only = [LIGHT,
                        {"overrides": {"rig": {"motors": {"mass_each_kg": 6.0}}}},
                        {"overrides": {"materials": {"steel": {"youngs_modulus_Pa": 2.1e11}}}},
                        {"overrides": {"rig": {"rails": {"fixing_stiffness_N_per_m3": 1.0e13}}}},
                        {"overrides": {"states": {"power_on": {"em_force_N": 3000.0}}}},
                        {"effects": {"base_support": {}}},
                        STEEL,
                        {"overrides": {"materials": {"aluminium": {"poisson_ratio": 0.30}}}}]
    own = [{"overrides": {"rig": {"table": {"thickness_m": 0.030}}}},
           {"overrides": {"rig": {"rails": {"spacing_m": 0.25}}}},
           {"overrides": {"rig": {"support": {"kind": "mounts"}}}},
           {"overrides": {"mesh": {"max_cell_size_m": 0.1}}}]
    assert [needs_own_model(h, cfg) for h in coefficient_only] == [False] * len(coefficient_only)
    assert [needs_own_model(h, cfg) for h in own] == [True] * len(own)
    assert needs_own_model(LIGHT)  # without the run's configuration: any model section builds its own


@pytest.fixture(scope="module")
def run_model():
    limit_threads(1)
    cfg = _cfg()
    return cfg, build_model(ModelSpec.from_config(cfg))


def test_a_coefficient_hypothesis_fits_as_on_its_own_model(run_model):
    cfg, model = run_model
    cfg_h = load_config(hypothesis_config(cfg, "steel", STEEL))
    fits = {}
    for key, m in (("run", model), ("own", build_model(ModelSpec.from_config(cfg_h)))):
        system = build_system(m, ModelSpec.from_config(cfg_h))
        data = measured_states(DiagnosisSettings.from_config(cfg_h), system)
        fits[key] = (fit_hypothesis(system, DiagnosisSettings.from_config(cfg_h), LinkedLaw.from_config(cfg_h), data, log=lambda msg: None), system)
    (run, s_run), (own, s_own) = fits["run"], fits["own"]
    # the run's model with the table's solid terms as terms of their own; the own model has none
    solid = {"K_solid_table", "K_lambda_table", "M_solid_table"}
    assert solid <= set(s_run.stiffness) | set(s_run.mass)
    assert not solid & (set(s_own.stiffness) | set(s_own.mass))
    assert s_run.stiffness["K0"] is model.stiffness["K0"]  # the run's K0 as it is: its shared basis serves
    # carried mass: the table at 7850 instead of 2700 kg/m^3 x 0.32 x 0.32 x 0.04 m and 3 x 1 kg of motors
    # instead of 3 x 3 kg
    default = build_system(model, ModelSpec.from_config(cfg)).carried_mass_kg
    volume = 0.32 * 0.32 * 0.04
    assert s_run.carried_mass_kg == pytest.approx(s_own.carried_mass_kg, rel=1e-9)
    assert s_run.carried_mass_kg == pytest.approx(default + (7850.0 - 2700.0) * volume - 6.0, rel=1e-9)
    print(f"chi2 run {run['chi2']:.9g} own {own['chi2']:.9g}, AICc run {run['aicc']:.6f} own {own['aicc']:.6f}")
    assert run["chi2"] == pytest.approx(own["chi2"], rel=1e-6)
    assert abs(run["aicc"] - own["aicc"]) < 0.1
    assert math.isfinite(run["chi2"]) and run["chi2"] > 0


def test_a_hypothesis_attraction_replaces_the_datasets(run_model, tmp_path):
    cfg, model = run_model
    path = tmp_path / "matrices.npz"
    save_model(model, path)
    cfg = dict(cfg, hypotheses={"pull": {"overrides": {"states": {"power_on": {"em_force_N": 3000.0}}}}})
    lines = []
    rec = run_hypothesis(HypothesisJob.from_config(cfg, "pull", check_hypothesis_effects), str(path), str(tmp_path / "fit.json"), log=lines.append)
    assert not rec["own_model"]
    forces = {s["state"]: s["em_force_N"] for s in rec["states"]}
    assert forces == {"power_off": 0.0, "power_on": 3000.0}
    assert any("power_on attraction 3000 N (the dataset's: 1000 N)" in line for line in lines)
    assert io.read_json(tmp_path / "fit.json")["chi2"] == pytest.approx(rec["chi2"], rel=1e-9)
