"""Hidden-effect cases: synthesise data from a truth the diagnosis never sees, then diagnose.

One case per library effect plus a decoy outside the library (``tests/hidden/*.yaml``).  In each:
the baseline fails (error clearly above the 0.2 % noise), the true effect ranks first, enabling it
brings the error down to the noise level; the decoy is reported as unexplained.  All cases share one
coarse model and one reduced solver (its subspace only grows), so the file runs in a few minutes.
"""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jointid.diagnosis import effects as E
from jointid.synthetic import generate as synth
from jointid.reporting.diagnosis_history import history_row
from jointid.diagnosis.loop import diagnose
from jointid.reporting.diagnosis_outputs import write_outputs
from jointid.diagnosis.variants import dataset_states
from jointid.data.dataset import read_dataset
from conftest import diagnosis_rig, ladder_text, print_summary
from jointid.config.typed_diagnosis import DiagnosisSettings
from conftest import truth_settings

ROOT = Path(__file__).resolve().parents[1]
CASES = sorted((ROOT / "tests" / "hidden").glob("*.yaml"))
SUMMARY: dict = {}


@pytest.fixture(scope="module")
def rig():
    """The coarse rig of the synthetic diagnosis tests (:func:`conftest.diagnosis_rig`)."""
    return diagnosis_rig()


def _true_effect(truth: dict):
    eff = truth.get("effects") or {}
    assert len(eff) <= 1, "one hidden effect per case"
    return next(iter(eff), None)


DEFAULT_CASES = ("added_mass_table",)  # the rest, the decoy among them: make test-all (marker extended);
# make test checks "nothing explains" on test_model_error_cases (a)


@pytest.mark.parametrize("case", [pytest.param(c, id=c.stem, marks=() if c.stem in DEFAULT_CASES
                                               else pytest.mark.extended) for c in CASES])
def test_hidden_effect_is_found(case, rig, tmp_path):
    cfg, system = rig["cfg"], rig["system"]
    truth = synth.load_truth(case)
    true = _true_effect(truth)
    synth.write_synthetic(truth, truth_settings(truth, cfg), tmp_path / "ds", model=rig["model"])
    ds = read_dataset(tmp_path / "ds", measuring_points=system.meta["points"])
    data = dataset_states(ds, system, DiagnosisSettings.from_config(cfg))
    sigma_pct = 100 * data[0].sigma_rel
    assert sigma_pct == pytest.approx(truth["noise"]["frequency_pct"])

    res = diagnose(system, DiagnosisSettings.from_config(cfg), data, solver=rig["solver"], log=lambda m: None)
    rig["solver"] = res.solver
    base = res.ladder[res.ladder.variant == "baseline"]
    base_max = float(base.max_abs_error_pct.max())
    # the baseline fails: far outside the noise
    assert base.p_value.iloc[0] < 1e-6
    assert base_max > 3 * sigma_pct
    top = res.ranking.iloc[0]
    rank = int(res.ranking.index[res.ranking.effect == true][0]) + 1 if true else None
    if true is None:
        # decoy outside the library: nothing may claim to explain it
        assert res.explained_by == "unexplained", res.verdict
        # the first sentence is the answer (nothing supported, or the supported part and the model error left)
        assert res.verdict.startswith(("Nothing is supported", "Supported effect:")), res.verdict
        assert "No listed effect explains the residual" in res.verdict
        assert not res.ranking.explains.any()
        SUMMARY[case.stem] = dict(text=res.verdict, true="(decoy)", rank="-", verdict="unexplained", before=base_max,
                                  after=float(top.max_abs_error_pct_after), ladder=ladder_text(res.ladder))
        return
    assert top.effect == true, res.ranking[["effect", "explained_fraction", "delta_aicc", "explains"]]
    assert bool(top.explains) and res.explained_by == true
    # the estimate recovers the hidden magnitude
    pname = E.EFFECTS[true].params[0].name
    assert top.estimate == pytest.approx(truth["effects"][true][pname], rel=0.25)

    # enabling it (one config change) brings the error down to the noise level
    on = diagnose(system, DiagnosisSettings.from_config(cfg), data, effects={true: {}}, candidates=[], solver=rig["solver"],
                  compare=False, drift=False, log=lambda m: None)
    cur = on.ladder[on.ladder.variant == f"+{true}"]
    assert cur.p_value.iloc[0] >= 0.01
    rms = float(np.sqrt(np.mean(cur.rms_error_pct ** 2)))
    assert rms < 1.5 * sigma_pct
    assert float(cur.max_abs_error_pct.max()) < 4 * sigma_pct
    assert on.verdict.startswith("The current model")
    SUMMARY[case.stem] = dict(text=res.verdict, true=true, rank=rank, verdict=res.explained_by, before=base_max,
                              after=float(cur.max_abs_error_pct.max()), rms_after=rms,
                              estimate=float(top.estimate), truth=truth["effects"][true][pname],
                              ladder=ladder_text(res.ladder))
    if true == "em_preload":
        # drift between the states is reported as evidence of a state-dependent effect
        assert res.drift.significant.any()
        # the report files and the history row
        write_outputs(res, tmp_path / "out", "synthetic", {"time_utc": "now", "config_hash": "x"})
        for f in ("ranking.csv", "ladder.csv", "compare.csv", "index.html", "drift.csv", "mac_power_on.csv"):
            assert (tmp_path / "out" / f).exists()
        rk = pd.read_csv(tmp_path / "out" / "ranking.csv")
        assert list(rk.columns[:6]) == ["rank", "effect", "explained_fraction", "score", "p_value", "delta_aicc"]
        assert "data:image/png;base64" in (tmp_path / "out" / "index.html").read_text()
        row = history_row(res, "synthetic", "x")
        assert row["variant"] == "baseline" and row["max_abs_error_pct"] == pytest.approx(base_max)


def test_summary_table(capsys):
    """Print rank of the true effect and error before/after for every case (pytest -s)."""
    print_summary(SUMMARY, capsys)
