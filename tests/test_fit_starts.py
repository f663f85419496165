"""Several starts of one fit (jointid.diagnosis.fitting.Diagnoser.fit_starts): a start whose search on the
subspace ends at an earlier start's optimum takes that fit instead of being refined and checked again.

Known truth: the coarse rig's em_preload dataset (tests/hidden/em_preload.yaml), the baseline fitted from its
configured start and from a start 20 % stiffer in every joint.  The second start, searched in full by a
diagnoser of its own, must end where the merged fit says (within the merge's rule, 5 % of a standard error)."""

import numpy as np

from jointid.config.typed_diagnosis import DiagnoseJob, DiagnosisSettings
from conftest import truth_settings

from test_memo import HIDDEN, frequency_rows_only


def _diagnoser(tmp_path):
    from conftest import diagnosis_rig

    from jointid.diagnosis.fitting import Diagnoser
    from jointid.diagnosis.variants import Variant
    from jointid.stages.diagnosis import _system_and_data
    from jointid.synthetic import generate as synth

    rig = diagnosis_rig()
    cfg = frequency_rows_only(rig["cfg"])
    truth = synth.load_truth(HIDDEN / "em_preload.yaml")
    if not (tmp_path / "ds").exists():
        synth.write_synthetic(truth, truth_settings(truth, cfg), tmp_path / "ds", model=rig["model"])
    system, data = _system_and_data(DiagnoseJob.from_config(cfg), tmp_path / "ds", None, rig["model"])
    settings = DiagnosisSettings.from_config(cfg)
    return Diagnoser(system, settings, data, log=lambda m: None), Variant(system, settings, [])


def test_a_start_that_reaches_an_earlier_optimum_takes_its_fit(tmp_path):
    from jointid.diagnosis.fitting import SAME_OPTIMUM, same_optimum

    diag, base = _diagnoser(tmp_path)
    x0 = base.x_start()
    x1 = x0 + np.log(1.2) * (np.abs(x0) > 10)  # the joints' log stiffness 20 % higher
    first, second = diag.fit_starts(base, [x0, x1])
    assert second.ev is first.ev  # merged: not refined and checked again

    alone, _ = _diagnoser(tmp_path)
    searched = alone.fit(base, x1)  # the second start searched to the end on its own
    se = np.sqrt(np.diag(first.scaled_covariance()))
    assert np.all(np.abs(searched.x - first.x) <= SAME_OPTIMUM * se), (searched.x - first.x) / se
    assert np.isclose(searched.chi2, first.chi2, rtol=1e-5), (searched.chi2, first.chi2)

    # the rule: the same pairing and every parameter within SAME_OPTIMUM standard errors
    assert same_optimum(first, first.x + 0.5 * SAME_OPTIMUM * se, first.ev.index)
    assert not same_optimum(first, first.x + 2 * SAME_OPTIMUM * se * (np.arange(len(se)) == 0), first.ev.index)
    other = [np.where(i >= 0, i + 1, i) for i in first.ev.index]
    assert not same_optimum(first, first.x, other)
