"""Mode shapes in the diagnosis's fits (issue 40, items 1 and 4; jointid.diagnosis.shape_residuals,
jointid.diagnosis.shape_proposal).

The tie case of tests/test_ambiguity.py (an elastic base support, true k_foundation 3e11 N/m^3, that a
compliant rail fixing imitates in the four lowest frequencies of two states):

* the shape rows' Jacobian (Nelson's method on the reduced model) agrees with finite differences on
  one subspace;
* a frequency-only dataset gives the same numbers with ``diagnosis.shape_residuals`` on and off;
* with shapes at MAC noise about 0.95 the truth ranks first by more than 4 in QAICc where frequencies
  alone tie;
* for the frequency-only variant the diagnosis proposes an accelerometer pair, and measuring the shapes
  there raises the truth's lead.
Run with ``-s`` to see the numbers.
"""

import re

import numpy as np
import pytest

from jointid.data.dataset import read_dataset, write_dataset
from jointid.synthetic import generate as synth
from jointid.diagnosis.fitting import Diagnoser
from jointid.diagnosis.loop import diagnose
from jointid.diagnosis.variants import Variant, dataset_states
from conftest import diagnosis_rig
from jointid.config.typed_diagnosis import DiagnosisSettings
from conftest import truth_settings

TRUTH_EFFECT = {"base_support": {"k_foundation_N_per_m3": 3.0e11}}
SHAPE_PCT = 23.0  # noise per DOF, % of the mode's RMS: MAC about 1 / (1 + 0.23^2) = 0.95
PAIR_PCT = 5.0  # noise of the proposed accelerometer pair (the proposal's assumption)
# the two tied effects and the richest other one (a preload law with its own profile): `make test`
# checks the tie and the switch on these three; `make test-all` checks the tie on the whole library
THREE = ["base_support", "rail_fixing", "em_preload"]
TWO = ["rail_fixing", "em_preload"]  # the switch's check: one effect of each kind (a stiffness term, a preload law)


@pytest.fixture(scope="module")
def rig():
    """The coarse rig of the synthetic diagnosis tests (:func:`conftest.diagnosis_rig`)."""
    return diagnosis_rig()


@pytest.fixture(scope="module")
def shaped(rig):
    """The synthesised tie case with shapes at SHAPE_PCT noise (read-only: :func:`states` copies what it changes)."""
    return synth.synthesise(truth(SHAPE_PCT), truth_settings(truth(SHAPE_PCT), rig["cfg"]), model=rig["model"])


def truth(shape_pct: float, *, shapes: bool = True) -> dict:
    return {"joints": {"k_normal_N_per_m3": 8.0e11, "k_lateral_N_per_m3": 6.0e11},
            "states": {"power_off": {"em_force_N": 0.0}, "power_on": {"em_force_N": 1000.0}},
            "effects": TRUTH_EFFECT,
            "measurement": {"band_Hz": [100.0, 3500.0], "max_modes": 4, "shapes": shapes},
            "noise": {"seed": 40, "frequency_pct": 0.2, "shape_pct": shape_pct}}


def states(rig, out, folder, shapes="all"):
    """Write a synthesised dataset (``shapes``: "all", None or a DataFrame of shape rows) and read its states."""
    sh = out["shapes"] if isinstance(shapes, str) else shapes
    cond = dict(out["conditions"])
    if sh is None:
        cond.pop("shape_uncertainty_pct", None)
    write_dataset(folder, out["modes"], sh, out["frf"], conditions=cond, measuring_points=out["points"])
    return dataset_states(read_dataset(folder, measuring_points=rig["system"].meta["points"]), rig["system"], DiagnosisSettings.from_config(rig["cfg"]))


def run(rig, data, shape_residuals=True, candidates=None, solver=None):
    """The diagnosis of ``data`` (``candidates``: the library effects tested; None: all; ``solver``: a
    reduced solver of an earlier run to go on with, its subspace grown, every answer still certified)."""
    cfg = {**rig["cfg"], "diagnosis": {**(rig["cfg"].get("diagnosis") or {}), "shape_residuals": shape_residuals}}
    return diagnose(rig["system"], DiagnosisSettings.from_config(cfg), data, candidates=candidates, solver=solver, log=lambda m: None,
                    drift=False, compare=False)


def lead(res) -> float:
    """QAICc of rail_fixing's refit less base_support's (> 0: the truth ahead)."""
    q = res.ranking.set_index("effect")["delta_qaicc"]
    return float(q["rail_fixing"] - q["base_support"])


def test_shape_jacobian_matches_finite_differences(rig, shaped, tmp_path):
    data = states(rig, shaped, tmp_path / "ds")
    cfg = {**rig["cfg"], "diagnosis": {**(rig["cfg"].get("diagnosis") or {}), "shape_residuals": True}}
    diag = Diagnoser(rig["system"], DiagnosisSettings.from_config(cfg), data, log=lambda m: None)
    base = Variant(rig["system"], DiagnosisSettings.from_config(cfg), [])
    x = np.log([8.0e11, 6.0e11])
    index = [p.model_index for p in diag.pair(diag.solve_states(base, x))]
    diag.evaluate(base, x, index)  # the subspace refined at x; then all three on that subspace
    ev = diag.evaluate(base, x, index, refine=False)
    shape = np.array([mode < 0 for _, mode in ev.rows])
    assert shape.sum() == 2 * 4 * len(rig["system"].labels) and ev.n_scales == 8
    alone = diag.evaluate(base, x, index, refine=False, jacobian=False)  # the misfit alone (the beta-P curve)
    assert np.array_equal(alone.r, ev.r) and alone.rows == ev.rows and alone.J.shape == (len(ev.r), 0)
    h = 1e-4  # the Ritz pairs carry round-off of the large reduced stiffness: a smaller step measures it
    for j in range(len(x)):
        step = np.eye(len(x))[j] * h
        fd = (diag.evaluate(base, x + step, index, refine=False).r
              - diag.evaluate(base, x - step, index, refine=False).r) / (2 * h)
        err = np.abs(fd[shape] - ev.J[shape, j]).max() / np.abs(fd[shape]).max()
        print(f"parameter {j}: shape-row Jacobian vs finite differences, max relative error {err:.1e}")
        assert err < 1e-4  # exact for the reduced model: the finite-difference error only


def test_frequency_only_dataset_gives_identical_numbers_with_the_switch_on_and_off(rig, tmp_path):
    data = states(rig, synth.synthesise(truth(0.0, shapes=False), truth_settings(truth(0.0, shapes=False), rig["cfg"]), model=rig["model"]), tmp_path / "ds")
    assert all(d.shapes is None for d in data)
    on, off = run(rig, data, True, TWO), run(rig, data, False, TWO)  # each from a fresh solver: bit for bit
    cols = ["delta_aicc", "delta_qaicc", "fit_chi2", "estimate", "ci95_low", "ci95_high"]
    a, b = on.ranking[cols].to_numpy(float), off.ranking[cols].to_numpy(float)
    assert list(on.ranking.effect) == list(off.ranking.effect)
    assert np.array_equal(a, b, equal_nan=True) and on.verdict == off.verdict
    assert not any("mode shapes in the fit" in n for n in on.notes)


@pytest.mark.parametrize("candidates", [THREE, pytest.param(None, marks=pytest.mark.extended)],
                         ids=["three effects", "whole library"])
def test_a_tie_is_broken_by_shapes(rig, shaped, tmp_path, candidates):
    """Frequencies alone tie base_support and rail_fixing; shapes at MAC about 0.95 rank the truth first."""
    out = shaped
    clean = synth.synthesise(truth(0.0), truth_settings(truth(0.0), rig["cfg"]), model=rig["model"])["shapes"]  # same seed: noise-free shapes
    macs = []
    for (s, m), g in out["shapes"].groupby(["state", "mode"]):
        c = clean[(clean.state == s) & (clean["mode"] == m)].value.to_numpy()
        v = g.value.to_numpy()
        macs.append((v @ c) ** 2 / ((v @ v) * (c @ c)))
    print(f"shape noise {SHAPE_PCT:g} % per DOF: MAC of the measured against the noise-free shapes "
          f"mean {np.mean(macs):.3f} (min {np.min(macs):.3f}, max {np.max(macs):.3f})")
    assert 0.93 <= np.mean(macs) <= 0.97
    data = states(rig, out, tmp_path / "ds")
    freq = run(rig, data, False, candidates)
    shapes = run(rig, data, True, candidates, solver=freq.solver)
    print(f"QAICc lead of base_support (truth) over rail_fixing: frequencies only {lead(freq):.2f}, "
          f"with shapes {lead(shapes):.2f}")
    print(freq.verdict, shapes.verdict, shapes.notes[0], sep="\n")
    assert abs(lead(freq)) < 4 and "cannot tell them apart" in freq.verdict
    assert shapes.ranking.iloc[0].effect == "base_support" and shapes.explained_by == "base_support"
    assert lead(shapes) > 4


@pytest.mark.extended
def test_the_next_measurement_names_an_accelerometer_pair_that_decides(rig, tmp_path):
    """The frequency-only variant: the proposals include an accelerometer position; the shapes measured
    there (noise 5 % of the pair's RMS, as proposed) raise the truth's lead."""
    out = synth.synthesise(truth(0.0), truth_settings(truth(0.0), rig["cfg"]), model=rig["model"])
    freq = run(rig, states(rig, out, tmp_path / "freq", shapes=None))
    nxt = freq.next_measurements
    assert "cannot tell them apart" in freq.verdict
    row = nxt[nxt.kind == "shape"].iloc[0]
    labels = re.findall(r"at (\w+:[xyz])", row.measurement)
    assert len(labels) == 2 and set(labels) <= set(rig["system"].labels), row.measurement
    print(f"proposed: {row.measurement}; expected chi-square difference {row.expected_delta_chi2:.1f}")
    sh = out["shapes"]
    keep = np.any([(sh.point == p) & (sh.direction == d) for p, d in (lab.split(":") for lab in labels)], axis=0)
    sh = sh[keep].copy()
    rng = np.random.default_rng(7)
    for _, g in sh.groupby(["state", "mode"]):
        sh.loc[g.index, "value"] = g.value + PAIR_PCT / 100 * np.sqrt(np.mean(g.value ** 2)) * rng.standard_normal(len(g))
    out["conditions"]["shape_uncertainty_pct"] = PAIR_PCT
    after = run(rig, states(rig, out, tmp_path / "pair", shapes=sh))
    print(f"QAICc lead of base_support (truth) over rail_fixing: frequencies only {lead(freq):.2f}, "
          f"with the pair's shapes {lead(after):.2f}")
    assert abs(lead(freq)) < 4
    assert lead(after) > 4 and after.explained_by == "base_support", after.verdict
