"""Known truths for the likelihood with model error (issue: honest when the model is wrong).

Synthetic data (fixed seeds, the coarse rig of the diagnosis tests) whose stated noise is wrong, or
whose truth holds something outside the library:

* (a) the noise stated 2x too small, nothing hidden: no effect is named; the verdict gives the misfit
  against the stated noise (about 2x) and the model error it implies;
* (b) the noise stated 2x too small, a hidden effect: that effect ranks first (or leads a tie that
  holds it), is supported, and the verdict reports the remaining model error;
* (c) the truth's moving mass 30 % lighter than the model's, bracketed by mass hypotheses: those
  admissible by QAICc span the true mass and their joints span the true joints;
* (d) a hidden library effect plus a decoy outside the library at the right noise: the library effect
  ranks first and is supported; the verdict reports the remaining model error;
* (e) the truth solved on a finer mesh: the discretisation error shows as a model error, and the
  hidden effect's widened 95 % interval covers the true value.
"""

import re

import pytest

from jointid.data.dataset import read_dataset
from jointid.synthetic import generate as synth
from jointid.diagnosis.loop import diagnose
from jointid.reporting.diagnosis_outputs import verdict_record
from jointid.diagnosis.variants import dataset_states
from conftest import diagnosis_rig
from jointid.config.typed_diagnosis import DiagnosisSettings
from jointid.config.typed import ModelSpec
from jointid.config.hypotheses import LinkedLaw
from conftest import truth_settings

JOINTS = {"k_normal_N_per_m3": 8.0e11, "k_lateral_N_per_m3": 6.0e11}
TWO_STATES = {"power_off": {"em_force_N": 0.0}, "power_on": {"em_force_N": 1000.0}}


@pytest.fixture(scope="module")
def rig():
    """The coarse rig of the synthetic diagnosis tests (:func:`conftest.diagnosis_rig`)."""
    return diagnosis_rig()


def run(rig, truth: dict, folder, candidates=None, **options):
    """Synthesise ``truth``, diagnose it (``candidates``: the library effects tested, None: all;
    ``options``: ``diagnosis`` settings of this case) and print the verdict (pytest -s)."""
    # a truth with overrides (another mesh, other masses) builds a model of its own
    synth.write_synthetic(truth, truth_settings(truth, rig["cfg"]), folder, model=None if truth.get("overrides") else rig["model"])
    ds = read_dataset(folder, measuring_points=rig["system"].meta["points"])
    data = dataset_states(ds, rig["system"], DiagnosisSettings.from_config(rig["cfg"]))
    cfg = {**rig["cfg"], "diagnosis": {**(rig["cfg"].get("diagnosis") or {}), **options}}
    res = diagnose(rig["system"], DiagnosisSettings.from_config(cfg), data, candidates=candidates, log=lambda m: None)
    print(f"\n[{folder.parent.name}] {res.verdict}")
    return res


def truth(*, seed: int, effects=None, perturbations=None, pct=0.2, stated=None) -> dict:
    t = {"joints": JOINTS, "states": TWO_STATES, "effects": effects or {},
         "measurement": {"band_Hz": [100.0, 3500.0], "max_modes": 10, "shapes": True},
         "noise": {"seed": seed, "frequency_pct": pct, "shape_pct": 2.0, "stated_frequency_pct": stated}}
    if perturbations:
        t["perturbations"] = perturbations
    return t


# make test: three effects that can absorb a global misfit (a preload law, a mass, a local mass), 36 s on the
# 2-core AMD EPYC of session 65; the whole library (382 s there: six refits twice, as the first calibration sat in
# a worse basin, then ten pairs) under make test-all.  The false-claim rate of the whole search on no-effect cases
# with the noise stated 2x small is measured in docs/validation.md.
A_CANDIDATES = ["em_preload", "added_mass_table", "added_mass_edge"]


@pytest.mark.parametrize("candidates", [A_CANDIDATES, pytest.param(None, marks=pytest.mark.extended)],
                         ids=["three effects", "whole library"])
def test_a_understated_noise_alone_names_no_effect(rig, tmp_path, candidates):
    res = run(rig, truth(seed=31, pct=0.4, stated=0.2), tmp_path / "ds", candidates=candidates)
    rec = verdict_record(res, "a", {})
    assert res.explained_by == "unexplained" and rec["supported"] == [], res.verdict
    assert not res.ranking.explains.any()
    me = res.model_error
    # the misfit is about twice the stated noise: c_hat near 4 (dof about 18: 2.2 .. 7 holds 95 %)
    assert 2.0 < me.c_hat < 8.0, me
    # the first sentence is the answer: nothing is supported, and by what factor the misfit exceeds the noise
    lead = re.match(r"Nothing is supported: .* the misfit is ([0-9.]+) times the stated noise", res.verdict)
    assert lead and float(lead.group(1)) == pytest.approx(me.c_hat ** 0.5, abs=0.051), res.verdict
    ratio = float(re.search(r"The misfit is about ([0-9.]+) times the stated noise", res.verdict).group(1))
    assert ratio == pytest.approx(me.c_hat ** 0.5, abs=0.051)
    assert "either the noise is understated by that factor" in res.verdict
    assert "outside the library" not in res.verdict
    # the model error that the understatement implies: sqrt(0.4^2 - 0.2^2) = 0.35 % in truth
    assert 0.15 < 100 * me.sigma_model_rel < 0.6


@pytest.mark.extended
def test_b_understated_noise_with_a_hidden_effect_ranks_it_first(rig, tmp_path):
    res = run(rig, truth(seed=32, pct=0.4, stated=0.2, effects={"added_mass_table": {"mass_kg": 4.0}}),
              tmp_path / "ds")
    top = res.ranking.iloc[0]
    tied = {top.effect} | set(str(top.indistinguishable_from or "").split(";")) - {""}
    assert "added_mass_table" in tied, res.ranking[["effect", "delta_qaicc", "support", "explains"]]
    assert top.effect == "added_mass_table" or len(tied) > 1
    assert top.support in ("strongly", "moderately"), res.verdict
    assert "added_mass_table removes" in res.verdict and "A model error of about" in res.verdict
    assert res.model_error.c_hat > 1.5


@pytest.mark.extended
def test_d_library_effect_plus_decoy_is_found_and_the_rest_called_model_error(rig, tmp_path):
    t = truth(seed=33, effects={"added_mass_table": {"mass_kg": 4.0}},
              perturbations=[{"kind": "carriage_joint_scale", "carriage": 0, "factor": 0.7}])
    res = run(rig, t, tmp_path / "ds", n_refit=3, n_combine=2)  # one pair: the search is not what is tested
    top = res.ranking.iloc[0]
    assert top.effect == "added_mass_table", res.ranking[["effect", "delta_qaicc", "support", "explains"]]
    assert res.model_error.c_hat > 1.0, res.verdict
    if not bool(top.explains):  # the decoy leaves a misfit above the noise: said with its size
        assert top.support == "strongly", res.verdict
        assert "A model error of about" in res.verdict, res.verdict


@pytest.mark.extended
def test_c_a_lighter_moving_mass_is_covered_by_the_reconstruction_range(rig, tmp_path):
    """The truth's moving mass (table and motors) is 30 % lighter than the analysis model's.  The
    analysis brackets the mass by hypotheses at 100, 85, 75, 65, 55 and 40 % (coefficient changes of one
    model, none of them the truth): those admissible (QAICc, :func:`jointid.reconstruction.ranking.admissible`)
    span the true mass, and the joint stiffness over them spans the true joints.

    With the shapes in the fits, the data resolve the mass to better than the 20 % steps this test used
    before (100, 80, 60, 40 %): 80 % led 60 % by delta QAICc 7.2, 97 % of the weight, so no set of those
    hypotheses held 70 %.  At 10 % steps 65 % trails 75 % by 4.5 and holds 10 % of the weight: admissible
    as part of the 95 % confidence set."""
    from jointid.config import load_config
    from jointid.config.hypotheses import hypothesis_config, needs_own_model
    from jointid.reconstruction.hypotheses import fit_hypothesis
    from jointid.reconstruction.ranking import rank_hypotheses, reconstruction_ranges
    from jointid.diagnosis.terms import build_system

    cfg = rig["cfg"]
    mat = cfg["rig"]["table"]["material"]
    rho = cfg["materials"][mat]["density_kg_per_m3"]
    motor_kg = cfg["rig"]["motors"]["mass_each_kg"]

    def lighter(f: float) -> dict:
        return {"overrides": {"materials": {mat: {"density_kg_per_m3": rho * f}},
                              "rig": {"motors": {"mass_each_kg": motor_kg * f}}}}

    t = truth(seed=34, effects={"em_preload": {"beta": 0.3}})
    t["overrides"] = lighter(0.7)["overrides"]
    synth.write_synthetic(t, truth_settings(t, cfg), tmp_path / "ds")  # the truth's own model, built from its overrides
    factors = {"mass_100": 1.0, "mass_85": 0.85, "mass_75": 0.75, "mass_65": 0.65, "mass_55": 0.55, "mass_40": 0.4}
    records = {}
    for name, f in factors.items():
        hyp = lighter(f)
        assert not needs_own_model(hyp, cfg)  # a coefficient change of the one model
        cfg_h = load_config(hypothesis_config(cfg, name, hyp))
        system = build_system(rig["model"], ModelSpec.from_config(cfg_h))
        ds = read_dataset(tmp_path / "ds", measuring_points=system.meta["points"])
        records[name] = fit_hypothesis(system, DiagnosisSettings.from_config(cfg_h), LinkedLaw.from_config(cfg_h), dataset_states(ds, system, DiagnosisSettings.from_config(cfg_h)), log=lambda m: None)
    rows, _, me = rank_hypotheses(records)
    admissible = [r["hypothesis"] for r in rows if r["admissible"]]
    print("\n[c]", me.sentence(), [(r["hypothesis"], round(r["delta_qaicc"], 1), round(r["chi2"], 1)) for r in rows])
    masses = [factors[n] for n in admissible]
    assert min(masses) <= 0.7 <= max(masses), rows
    ranges = {(r["quantity"], r["state"]): r for r in reconstruction_ranges(records, rows)}
    for par, true in JOINTS.items():
        r = ranges[(par, "power_off")]  # power off: the joints without the attraction's preload
        assert r["value_min"] <= true <= r["value_max"], (par, r)


@pytest.mark.extended
def test_e_truth_on_a_finer_mesh_the_effect_interval_covers_it(rig, tmp_path):
    """The truth solved on a mesh refined once (the analysis's mesh is stiffer), right noise: the
    mesh's discretisation error is a model error the fit shows, and the hidden effect's 95 % interval,
    widened by it, covers the true value."""
    t = truth(seed=35, effects={"added_mass_table": {"mass_kg": 4.0}})
    t["overrides"] = {"mesh": {"refine": 2}}
    res = run(rig, t, tmp_path / "ds", n_refit=3, n_combine=2)
    row = res.ranking.set_index("effect").loc["added_mass_table"]
    print("\n[e]", res.model_error.sentence(), row[["estimate", "ci95_low", "ci95_high", "interval_scale"]].to_dict())
    assert res.model_error.c_hat > 1.5  # the mesh's error shows as a model error above the noise
    assert row.interval_scale > 1.2  # and widens the interval
    assert row.ci95_low <= 4.0 <= row.ci95_high, row[["estimate", "ci95_low", "ci95_high", "interval_scale"]]

