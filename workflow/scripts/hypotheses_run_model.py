"""Snakemake adapter: fit the hypotheses that change only coefficients of the run's model, in one job."""
from jointid.config.hypotheses import HypothesisJob
from jointid.reconstruction.hypotheses import check_hypothesis_effects
from jointid.stages.hypotheses import run_hypotheses
from jointid.stages.runner import run_script


def _jobs(cfg, names):
    return [HypothesisJob.from_config(cfg, name, check_hypothesis_effects) for name in names]


run_script(snakemake, lambda cfg, inp, out: run_hypotheses(
    _jobs(cfg, snakemake.params.shared), inp.matrices, list(out.fits), basis=inp.basis, others=list(inp.others),
    apart=_jobs(cfg, snakemake.params.separate), apart_jsons=list(out.apart)), provenance=True)
