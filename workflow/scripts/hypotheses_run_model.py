"""Snakemake adapter: fit the hypotheses that change only coefficients of the run's model, in one job."""
from jointid.config.hypotheses import HypothesisJob
from jointid.reconstruction.hypotheses import check_hypothesis_effects
from jointid.stages.hypotheses import run_hypotheses
from jointid.stages.runner import run_script

run_script(snakemake, lambda cfg, inp, out: run_hypotheses(
    [HypothesisJob.from_config(cfg, name, check_hypothesis_effects) for name in cfg["hypotheses"]], inp.matrices,
    list(out.fits), basis=inp.basis, others=list(inp.others)), provenance=True)
